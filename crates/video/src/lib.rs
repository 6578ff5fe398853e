//! Camera streams through ffmpeg (Debian's package: libx264 for H.264, libsvtav1 for AV1).
//!
//! [`VideoWriter`] streams RGB frames into an ffmpeg process as they are rendered, so a
//! whole episode of images is never held in memory, and publishes the file atomically
//! (temporary name, renamed by [`VideoWriter::finish`]). Output is bit-exact for the same
//! frames and settings on every machine (ffmpeg's bitexact flags, and one x264 thread:
//! x264's output depends on its thread count, which by default follows the machine's cores,
//! so shards on nodes of different sizes would otherwise encode different bytes).
//! [`probe`] and [`decode_rgb`] read videos back, for checks and tests; [`VideoReader`]
//! streams decoded frames one at a time; [`concat_copy`] joins videos of the same codec
//! and size into one file by stream copy (no re-encode), with continuous timestamps.
//! [`encoder_versions`] names the ffmpeg and x264 that decide the bytes.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};

use serde::{Deserialize, Serialize};

mod depth;
mod versions;
pub use depth::{DepthVideoWriter, decode_gray12};
pub use versions::{EncoderVersions, encoder_versions};

/// Errors of video encoding and decoding; each names the file.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum VideoError {
    /// ffmpeg or ffprobe could not be started.
    #[error("cannot run {program} for '{path}': {source} (install Debian's ffmpeg package)")]
    Spawn {
        /// The program.
        program: String,
        /// The video file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// ffmpeg or ffprobe failed.
    #[error("{program} failed on '{path}': {message}")]
    Failed {
        /// The program.
        program: String,
        /// The video file.
        path: PathBuf,
        /// Its error output.
        message: String,
    },
    /// A frame of the wrong size was given.
    #[error("'{path}': frame {frame} has {found} bytes, expected {expected} ({width}x{height})")]
    FrameSize {
        /// The video file.
        path: PathBuf,
        /// Frame index.
        frame: usize,
        /// Bytes given.
        found: usize,
        /// Bytes expected.
        expected: usize,
        /// Width.
        width: u32,
        /// Height.
        height: u32,
    },
    /// Writing to ffmpeg or renaming the output failed.
    #[error("'{path}': {source}")]
    Io {
        /// The video file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// Video codec and its quality setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "codec")]
pub enum Codec {
    /// H.264 (libx264), yuv420p, profile high: what the DexJoCo recorder writes (crf 21).
    H264 {
        /// Constant rate factor (lower = better; 21 in DexJoCo).
        crf: u8,
    },
    /// AV1 (libsvtav1), yuv420p: what lerobot encodes by default.
    Av1 {
        /// Constant rate factor (lerobot uses 30).
        crf: u8,
        /// SVT-AV1 preset (0 slowest .. 13 fastest).
        preset: u8,
    },
}

impl Codec {
    /// The DexJoCo recorder's setting: H.264, crf 21.
    pub const DEXJOCO: Self = Self::H264 { crf: 21 };
}

/// Frame size, rate and codec of a video.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VideoSpec {
    /// Width in pixels (even, for yuv420p).
    pub width: u32,
    /// Height in pixels (even, for yuv420p).
    pub height: u32,
    /// Frames per second.
    pub fps: u32,
    /// Codec.
    pub codec: Codec,
}

/// The ffmpeg program: `$DEXJOCO_FFMPEG` or `ffmpeg` on PATH.
pub fn ffmpeg_program() -> PathBuf {
    std::env::var_os("DEXJOCO_FFMPEG").map_or_else(|| "ffmpeg".into(), PathBuf::from)
}

/// CPU seconds (user + system) of this process's finished child processes, such as the
/// encoders of finished [`VideoWriter`]s, from `/proc/self/stat` (Linux); the difference
/// over a piece of work is what its encoders cost. `None` where that file is unreadable.
pub fn finished_children_cpu_seconds() -> Option<f64> {
    // The kernel reports these in USER_HZ ticks, 100 per second on Linux.
    const TICKS_PER_SECOND: f64 = 100.0;
    let stat = fs_err::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces) start with field 3, `state`;
    // cutime and cstime are fields 16 and 17.
    let rest = &stat[stat.rfind(')')? + 1..];
    let mut fields = rest.split_whitespace().skip(13);
    let cutime: f64 = fields.next()?.parse().ok()?;
    let cstime: f64 = fields.next()?.parse().ok()?;
    Some((cutime + cstime) / TICKS_PER_SECOND)
}

/// Starts an ffmpeg command; a failure to start names the video file.
fn spawn_ffmpeg(cmd: &mut Command, path: &Path) -> Result<Child, VideoError> {
    cmd.spawn().map_err(|source| VideoError::Spawn {
        program: ffmpeg_program().display().to_string(),
        path: path.into(),
        source,
    })
}

fn ffprobe_program() -> PathBuf {
    let ff = ffmpeg_program();
    match ff.parent() {
        Some(dir) if !dir.as_os_str().is_empty() => dir.join("ffprobe"),
        _ => "ffprobe".into(),
    }
}

/// Streams RGB frames into a video file through an ffmpeg process.
#[derive(Debug)]
pub struct VideoWriter {
    child: Option<Child>,
    stdin: Option<ChildStdin>,
    path: PathBuf,
    tmp: PathBuf,
    spec: VideoSpec,
    /// Bytes of one raw input frame.
    frame_bytes: usize,
    frames: usize,
}

impl VideoWriter {
    /// Starts an encoder writing to a temporary file beside `path`.
    pub fn create(path: impl Into<PathBuf>, spec: VideoSpec) -> Result<Self, VideoError> {
        Self::create_with(path, spec, None)
    }

    /// As [`VideoWriter::create`], with a keyframe every `gop` frames when given (lerobot
    /// encodes with a GOP of 2 so that random access decodes few frames).
    pub fn create_with(
        path: impl Into<PathBuf>,
        spec: VideoSpec,
        gop: Option<u32>,
    ) -> Result<Self, VideoError> {
        let mut cmd = Command::new(ffmpeg_program());
        match spec.codec {
            Codec::H264 { crf } => {
                cmd.args([
                    "-c:v",
                    "libx264",
                    // Bytes independent of the machine's core count (see the crate doc);
                    // parallelism comes from the workers, one encoder each.
                    "-threads",
                    "1",
                    "-profile:v",
                    "high",
                    "-crf",
                    &crf.to_string(),
                ]);
            }
            Codec::Av1 { crf, preset } => {
                cmd.args([
                    "-c:v",
                    "libsvtav1",
                    "-crf",
                    &crf.to_string(),
                    "-preset",
                    &preset.to_string(),
                ]);
            }
        }
        if let Some(g) = gop {
            cmd.args(["-g", &g.max(1).to_string()]);
        }
        cmd.args(["-pix_fmt", "yuv420p"]);
        let frame_bytes = spec.width as usize * spec.height as usize * 3;
        Self::start(path.into(), spec, "rgb24", frame_bytes, cmd)
    }

    /// Starts `cmd` (ffmpeg with its encoder and output pixel format set) reading raw
    /// frames of `input_pix_fmt`, `frame_bytes` each, from its stdin, writing an mp4 to a
    /// temporary file beside `path`.
    pub(crate) fn start(
        path: PathBuf,
        spec: VideoSpec,
        input_pix_fmt: &str,
        frame_bytes: usize,
        encoder: Command,
    ) -> Result<Self, VideoError> {
        let name = path
            .file_name()
            .map_or_else(|| "video".into(), |n| n.to_string_lossy().into_owned());
        let tmp = path.with_file_name(format!(".{name}.partial.mp4"));
        let mut cmd = Command::new(encoder.get_program());
        cmd.args(["-hide_banner", "-loglevel", "error", "-nostdin", "-y"])
            .args(["-f", "rawvideo", "-pix_fmt", input_pix_fmt])
            .args(["-s", &format!("{}x{}", spec.width, spec.height)])
            .args(["-framerate", &spec.fps.to_string(), "-i", "-"])
            .args(encoder.get_args())
            .args(["-r", &spec.fps.to_string()])
            .args([
                "-fflags",
                "+bitexact",
                "-flags:v",
                "+bitexact",
                "-map_metadata",
                "-1",
            ])
            .args(["-f", "mp4"])
            .arg(&tmp)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        let mut child = spawn_ffmpeg(&mut cmd, &path)?;
        let stdin = child.stdin.take();
        Ok(Self {
            child: Some(child),
            stdin,
            path,
            tmp,
            spec,
            frame_bytes,
            frames: 0,
        })
    }

    /// Frames written so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Appends one RGB8 frame (rows top to bottom).
    pub fn write_frame(&mut self, rgb: &[u8]) -> Result<(), VideoError> {
        let expected = self.frame_bytes;
        if rgb.len() != expected {
            return Err(VideoError::FrameSize {
                path: self.path.clone(),
                frame: self.frames,
                found: rgb.len(),
                expected,
                width: self.spec.width,
                height: self.spec.height,
            });
        }
        let stdin = self.stdin.as_mut().expect("stdin is open until finish");
        if let Err(source) = stdin.write_all(rgb) {
            // ffmpeg exited early: its stderr says why.
            return Err(self.fail_with(source));
        }
        self.frames += 1;
        Ok(())
    }

    fn fail_with(&mut self, source: std::io::Error) -> VideoError {
        self.stdin = None;
        let message = self
            .child
            .take()
            .and_then(|c| c.wait_with_output().ok())
            .map(|o| String::from_utf8_lossy(&o.stderr).trim().to_owned())
            .filter(|m| !m.is_empty());
        let _ = fs_err::remove_file(&self.tmp);
        match message {
            Some(message) => VideoError::Failed {
                program: "ffmpeg".into(),
                path: self.path.clone(),
                message,
            },
            None => VideoError::Io {
                path: self.path.clone(),
                source,
            },
        }
    }

    /// Closes the stream, waits for ffmpeg and moves the file into place. Returns the
    /// number of frames.
    pub fn finish(mut self) -> Result<usize, VideoError> {
        drop(self.stdin.take());
        let child = self.child.take().expect("child runs until finish");
        let out = child.wait_with_output().map_err(|source| VideoError::Io {
            path: self.path.clone(),
            source,
        })?;
        if !out.status.success() {
            let _ = fs_err::remove_file(&self.tmp);
            return Err(VideoError::Failed {
                program: "ffmpeg".into(),
                path: self.path.clone(),
                message: String::from_utf8_lossy(&out.stderr).trim().to_owned(),
            });
        }
        fs_err::rename(&self.tmp, &self.path).map_err(|source| VideoError::Io {
            path: self.path.clone(),
            source,
        })?;
        Ok(self.frames)
    }
}

impl Drop for VideoWriter {
    /// An unfinished writer leaves nothing behind: the encoder is stopped and its
    /// temporary file removed.
    fn drop(&mut self) {
        if let Some(mut child) = self.child.take() {
            drop(self.stdin.take());
            let _ = child.kill();
            let _ = child.wait();
            let _ = fs_err::remove_file(&self.tmp);
        }
    }
}

/// What ffprobe says about a video's first stream.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VideoInfo {
    /// Codec name (`h264`, `av1`).
    pub codec: String,
    /// Codec profile (`High`), when reported.
    pub profile: Option<String>,
    /// Pixel format (`yuv420p`).
    pub pix_fmt: String,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Frames per second.
    pub fps: f64,
    /// Number of frames (counted by decoding the packets).
    pub frames: u64,
}

fn run(program: PathBuf, args: &[&str], path: &Path) -> Result<Vec<u8>, VideoError> {
    let out = Command::new(&program)
        .args(args)
        .output()
        .map_err(|source| VideoError::Spawn {
            program: program.display().to_string(),
            path: path.into(),
            source,
        })?;
    if !out.status.success() {
        return Err(VideoError::Failed {
            program: program.display().to_string(),
            path: path.into(),
            message: String::from_utf8_lossy(&out.stderr).trim().to_owned(),
        });
    }
    Ok(out.stdout)
}

/// Codec, size, rate and frame count of a video (with ffprobe).
pub fn probe(path: &Path) -> Result<VideoInfo, VideoError> {
    let p = path.to_string_lossy();
    let out = run(
        ffprobe_program(),
        &[
            "-v",
            "error",
            "-select_streams",
            "v:0",
            "-count_packets",
            "-show_streams",
            "-of",
            "json",
            &p,
        ],
        path,
    )?;
    let bad = |m: &str| VideoError::Failed {
        program: "ffprobe".into(),
        path: path.into(),
        message: m.into(),
    };
    let json: serde_json::Value = serde_json::from_slice(&out).map_err(|e| bad(&e.to_string()))?;
    let s = json["streams"]
        .get(0)
        .ok_or_else(|| bad("no video stream"))?;
    let rate = s["avg_frame_rate"].as_str().unwrap_or("0/1");
    let fps = match rate.split_once('/') {
        Some((n, d)) => n.parse::<f64>().unwrap_or(0.0) / d.parse::<f64>().unwrap_or(1.0).max(1e-9),
        None => rate.parse().unwrap_or(0.0),
    };
    Ok(VideoInfo {
        codec: s["codec_name"].as_str().unwrap_or("").into(),
        profile: s["profile"].as_str().map(Into::into),
        pix_fmt: s["pix_fmt"].as_str().unwrap_or("").into(),
        width: s["width"].as_u64().unwrap_or(0) as u32,
        height: s["height"].as_u64().unwrap_or(0) as u32,
        fps,
        frames: s["nb_read_packets"]
            .as_str()
            .and_then(|n| n.parse().ok())
            .unwrap_or(0),
    })
}

/// Decodes every frame to RGB8 (rows top to bottom), one `Vec` per frame.
pub fn decode_rgb(path: &Path) -> Result<Vec<Vec<u8>>, VideoError> {
    let (raw, size) = decode_raw(path, "rgb24", 3)?;
    Ok(raw.chunks_exact(size).map(<[u8]>::to_vec).collect())
}

/// Decodes every frame of `path` into one buffer of `pix_fmt` (`bytes_per_pixel` bytes a
/// pixel); returns it and the size of one frame in bytes, checked to divide it.
pub(crate) fn decode_raw(
    path: &Path,
    pix_fmt: &str,
    bytes_per_pixel: usize,
) -> Result<(Vec<u8>, usize), VideoError> {
    let info = probe(path)?;
    let p = path.to_string_lossy();
    let raw = run(
        ffmpeg_program(),
        &[
            "-v", "error", "-nostdin", "-i", &p, "-f", "rawvideo", "-pix_fmt", pix_fmt, "-",
        ],
        path,
    )?;
    let size = info.width as usize * info.height as usize * bytes_per_pixel;
    if size == 0 || raw.len() % size != 0 {
        return Err(VideoError::Failed {
            program: "ffmpeg".into(),
            path: path.into(),
            message: format!(
                "decoded {} bytes, not a whole number of {size}-byte frames",
                raw.len()
            ),
        });
    }
    Ok((raw, size))
}

/// Streams decoded RGB8 frames of a video from an ffmpeg process, one at a time, so a
/// whole video is never held in memory.
#[derive(Debug)]
pub struct VideoReader {
    child: Child,
    stdout: std::process::ChildStdout,
    path: PathBuf,
    width: u32,
    height: u32,
    frame: usize,
}

impl VideoReader {
    /// Starts decoding `path`, scaled to `size` (width, height) when given.
    pub fn open(path: &Path, size: Option<(u32, u32)>) -> Result<Self, VideoError> {
        let (width, height) = match size {
            Some(s) => s,
            None => {
                let info = probe(path)?;
                (info.width, info.height)
            }
        };
        let mut cmd = Command::new(ffmpeg_program());
        cmd.args(["-v", "error", "-nostdin", "-i"]).arg(path);
        if size.is_some() {
            cmd.args(["-vf", &format!("scale={width}:{height}:flags=area")]);
        }
        cmd.args(["-f", "rawvideo", "-pix_fmt", "rgb24", "-"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let mut child = spawn_ffmpeg(&mut cmd, path)?;
        let stdout = child.stdout.take().expect("piped stdout");
        Ok(Self {
            child,
            stdout,
            path: path.into(),
            width,
            height,
            frame: 0,
        })
    }

    /// Frame width and height.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Reads the next frame into `buf` (resized to width x height x 3); false at the end.
    pub fn next_frame(&mut self, buf: &mut Vec<u8>) -> Result<bool, VideoError> {
        use std::io::Read;
        let size = self.width as usize * self.height as usize * 3;
        buf.resize(size, 0);
        let mut filled = 0;
        while filled < size {
            match self.stdout.read(&mut buf[filled..]) {
                Ok(0) => break,
                Ok(n) => filled += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(source) => {
                    return Err(VideoError::Io {
                        path: self.path.clone(),
                        source,
                    });
                }
            }
        }
        if filled == size {
            self.frame += 1;
            return Ok(true);
        }
        let status = self.child.wait().map_err(|source| VideoError::Io {
            path: self.path.clone(),
            source,
        })?;
        if !status.success() || filled != 0 {
            let mut message = String::new();
            if let Some(mut e) = self.child.stderr.take() {
                use std::io::Read;
                let _ = e.read_to_string(&mut message);
            }
            return Err(VideoError::Failed {
                program: "ffmpeg".into(),
                path: self.path.clone(),
                message: format!(
                    "decoding stopped after {} frames ({status}): {}",
                    self.frame,
                    message.trim()
                ),
            });
        }
        Ok(false)
    }
}

impl Drop for VideoReader {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Joins videos of one codec, size and frame rate `fps` into `out` by stream copy
/// (ffmpeg's concat demuxer): no re-encode, and the timestamps run on continuously, so
/// frame k of input i is at exactly (frames before input i + k) / fps. (The demuxer
/// offsets each input by its container duration, rounded to milliseconds; the `setts`
/// filter snaps every timestamp back onto the frame grid.) Written to a temporary file
/// beside `out` and renamed when complete.
pub fn concat_copy(inputs: &[PathBuf], out: &Path, fps: u32) -> Result<(), VideoError> {
    let name = out
        .file_name()
        .map_or_else(|| "video".into(), |n| n.to_string_lossy().into_owned());
    let list = out.with_file_name(format!(".{name}.concat.txt"));
    let tmp = out.with_file_name(format!(".{name}.partial.mp4"));
    let mut text = String::from("ffconcat version 1.0\n");
    for p in inputs {
        let abs = std::path::absolute(p).map_err(|source| VideoError::Io {
            path: p.clone(),
            source,
        })?;
        // The concat list quotes paths with single quotes; a quote is written as '\''.
        let quoted = abs.to_string_lossy().replace('\'', "'\\''");
        text.push_str(&format!("file '{quoted}'\n"));
    }
    fs_err::write(&list, text).map_err(|source| VideoError::Io {
        path: list.clone(),
        source,
    })?;
    let list_s = list.to_string_lossy().into_owned();
    let tmp_s = tmp.to_string_lossy().into_owned();
    let snap =
        format!("setts=pts=round(PTS*TB*{fps})/(TB*{fps}):dts=round(DTS*TB*{fps})/(TB*{fps})");
    let result = run(
        ffmpeg_program(),
        &[
            "-hide_banner",
            "-loglevel",
            "error",
            "-nostdin",
            "-y",
            "-f",
            "concat",
            "-safe",
            "0",
            "-i",
            &list_s,
            "-map",
            "0:v:0",
            "-c",
            "copy",
            "-bsf:v",
            &snap,
            "-fflags",
            "+bitexact",
            "-map_metadata",
            "-1",
            "-f",
            "mp4",
            &tmp_s,
        ],
        out,
    );
    let _ = fs_err::remove_file(&list);
    if let Err(e) = result {
        let _ = fs_err::remove_file(&tmp);
        return Err(e);
    }
    fs_err::rename(&tmp, out).map_err(|source| VideoError::Io {
        path: out.into(),
        source,
    })
}

/// Presentation timestamps (seconds) of every frame of the first video stream, in
/// presentation order.
pub fn frame_times(path: &Path) -> Result<Vec<f64>, VideoError> {
    let p = path.to_string_lossy();
    let out = run(
        ffprobe_program(),
        &[
            "-v",
            "error",
            "-select_streams",
            "v:0",
            "-show_entries",
            "packet=pts_time",
            "-of",
            "csv=p=0",
            &p,
        ],
        path,
    )?;
    let mut t: Vec<f64> = String::from_utf8_lossy(&out)
        .lines()
        .filter_map(|l| l.trim().trim_end_matches(',').parse().ok())
        .collect();
    t.sort_by(f64::total_cmp);
    Ok(t)
}
