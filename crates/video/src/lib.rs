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
mod probe;
mod program;
mod read;
mod transcode;
mod versions;
pub use depth::{DepthVideoWriter, decode_gray12};
pub(crate) use read::decode_raw;
pub use read::{VideoReader, decode_rgb};
pub use transcode::{
    CutPoints, Encoding, SmartCut, StatedEncoding, X264Settings, candidate_encodings, smart_cut,
    transcode, x264_settings,
};

pub use probe::{
    Packet, VideoInfo, frame_times, keyframe_indices, packets_in_decoding_order, probe,
    probe_with_ffmpeg_alone,
};
pub use program::{Ffmpeg, FfmpegSource, ffmpeg_program, locate_ffmpeg, locate_ffprobe, which};
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
    /// H.264 (libx264), yuv420p, profile high at most (x264's ultrafast streams are
    /// Constrained Baseline); the DexJoCo recorder writes crf 21, preset medium. crf 0 is
    /// lossless RGB instead (libx264rgb, qp 0, the rendered frames bit for bit; large:
    /// for measurements and for re-encoding later).
    H264 {
        /// Constant rate factor (lower = better; 21 in DexJoCo; 0 lossless).
        crf: u8,
        /// x264's speed preset (records made before it was chosen: medium).
        #[serde(default)]
        preset: X264Preset,
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
    /// The DexJoCo recorder's setting: H.264, crf 21, x264's default preset (medium).
    pub const DEXJOCO: Self = Self::H264 {
        crf: 21,
        preset: X264Preset::Medium,
    };
}

/// x264's speed presets (faster presets spend less CPU per frame for somewhat larger
/// files at the same crf).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum X264Preset {
    /// `ultrafast`.
    Ultrafast,
    /// `superfast`.
    Superfast,
    /// `veryfast`.
    Veryfast,
    /// `faster`.
    Faster,
    /// `fast`.
    Fast,
    /// `medium`, x264's default.
    #[default]
    Medium,
    /// `slow`.
    Slow,
}

impl X264Preset {
    /// Every preset, fastest first.
    pub const ALL: [Self; 7] = [
        Self::Ultrafast,
        Self::Superfast,
        Self::Veryfast,
        Self::Faster,
        Self::Fast,
        Self::Medium,
        Self::Slow,
    ];

    /// The name x264 and ffmpeg give it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ultrafast => "ultrafast",
            Self::Superfast => "superfast",
            Self::Veryfast => "veryfast",
            Self::Faster => "faster",
            Self::Fast => "fast",
            Self::Medium => "medium",
            Self::Slow => "slow",
        }
    }
}

impl std::fmt::Display for X264Preset {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for X264Preset {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = Self::ALL.iter().map(|p| p.name()).collect();
                format!("unknown x264 preset '{s}' (one of {})", names.join(", "))
            })
    }
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

/// Where an encoder puts keyframes (closed GOPs: a keyframe starts a stream copy cut, and
/// decoding a frame at random starts at the keyframe before it).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Keyframes {
    /// At most this many frames from one keyframe to the next (ffmpeg's `-g`); the
    /// encoder's default (x264: 250) when `None`. lerobot encodes with 2 so that random
    /// access decodes few frames.
    pub interval: Option<u32>,
    /// Frames that must be keyframes, such as an episode's first kept frame after its
    /// static leading frames, so that `convert` cuts there by stream copy.
    pub at: Vec<usize>,
}

impl Keyframes {
    /// ffmpeg's `-force_key_frames` value for [`Keyframes::at`] at `fps`: an `expr:` of
    /// the frame numbers for a few, else a list of the frames' times (ffmpeg's expression
    /// parser refuses a few hundred terms; it rounds each time to the nearest frame).
    fn force_value(&self, fps: u32) -> Option<String> {
        const MOST_TERMS: usize = 16;
        let mut at: Vec<usize> = self.at.iter().copied().filter(|&k| k > 0).collect();
        at.sort_unstable();
        at.dedup();
        if at.is_empty() {
            return None;
        }
        if at.len() <= MOST_TERMS {
            let terms: Vec<String> = at.iter().map(|k| format!("eq(n,{k})")).collect();
            return Some(format!("expr:{}", terms.join("+")));
        }
        let fps = f64::from(fps.max(1));
        let times: Vec<String> = at
            .iter()
            .map(|k| format!("{:.6}", *k as f64 / fps))
            .collect();
        Some(times.join(","))
    }
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
        Self::create_with(path, spec, &Keyframes::default())
    }

    /// As [`VideoWriter::create`], with the keyframes `keyframes` asks for.
    pub fn create_with(
        path: impl Into<PathBuf>,
        spec: VideoSpec,
        keyframes: &Keyframes,
    ) -> Result<Self, VideoError> {
        let frame_bytes = spec.width as usize * spec.height as usize * 3;
        Self::start(
            path.into(),
            spec,
            "rgb24",
            frame_bytes,
            encoder(spec, keyframes),
        )
    }

    /// As [`VideoWriter::create_with`], fed decoded yuv420p frames (`width * height * 3 / 2`
    /// bytes each, as [`transcode`] passes them on): no colour conversion on the way in.
    pub fn create_yuv420p(
        path: impl Into<PathBuf>,
        spec: VideoSpec,
        keyframes: &Keyframes,
    ) -> Result<Self, VideoError> {
        let frame_bytes = spec.width as usize * spec.height as usize * 3 / 2;
        Self::start(
            path.into(),
            spec,
            "yuv420p",
            frame_bytes,
            encoder(spec, keyframes),
        )
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

    /// Appends one frame: RGB8, rows top to bottom (yuv420p planes for a writer made by
    /// [`VideoWriter::create_yuv420p`]).
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

/// ffmpeg's encoder arguments for `spec` and `keyframes`, with the output pixel format.
fn encoder(spec: VideoSpec, keyframes: &Keyframes) -> Command {
    let mut cmd = Command::new(ffmpeg_program());
    let mut pix_fmt = "yuv420p";
    match spec.codec {
        Codec::H264 { crf: 0, preset } => {
            // Lossless RGB: the frames as rendered.
            cmd.args(["-c:v", "libx264rgb", "-threads", "1", "-qp", "0"]);
            cmd.args(["-preset", preset.name()]);
            pix_fmt = "rgb24";
        }
        Codec::H264 { crf, preset } => {
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
                "-preset",
                preset.name(),
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
    if let Some(g) = keyframes.interval {
        cmd.args(["-g", &g.max(1).to_string()]);
    }
    if let Some(value) = keyframes.force_value(spec.fps) {
        cmd.args(["-force_key_frames", &value]);
    }
    cmd.args(["-pix_fmt", pix_fmt]);
    cmd
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

pub(crate) fn run(program: PathBuf, args: &[&str], path: &Path) -> Result<Vec<u8>, VideoError> {
    Ok(run_output(program, args, path)?.stdout)
}

/// Runs `program` with `args` about the video `path`; its whole output when it succeeds,
/// else an error naming the program, the file and what it printed on stderr.
pub(crate) fn run_output(
    program: PathBuf,
    args: &[&str],
    path: &Path,
) -> Result<std::process::Output, VideoError> {
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
    Ok(out)
}

/// One input of [`concat_copy`]: a video, how many of its leading frames to cut and how
/// many frames to keep after them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ConcatInput {
    /// The video.
    pub path: PathBuf,
    /// Leading frames left out; frame `skip` must be a keyframe (see [`keyframe_indices`]),
    /// where stream copy can start.
    pub skip: usize,
    /// Frames kept after `skip`; `None`: to the end. Where the kept frames end before the
    /// video does, the frame after them must be a keyframe that starts a closed group of
    /// pictures (as where two episodes encoded apart were joined): the stream is cut
    /// there in decoding order.
    pub take: Option<usize>,
}

impl ConcatInput {
    /// All of `path` from its first frame.
    pub fn whole(path: impl Into<PathBuf>) -> Self {
        Self {
            path: path.into(),
            skip: 0,
            take: None,
        }
    }
}

/// The concat list's lines for `input` after its `file` line: `inpoint`, and with a
/// `take`, the `outpoint` (between the decoding times of the last kept packet and the
/// first packet after the kept frames, so that packet and all after it are left out) and
/// the `duration` the next input is offset by.
fn concat_points(
    input: &ConcatInput,
    fps: u32,
    probed: &mut std::collections::HashMap<PathBuf, Probed>,
) -> Result<String, VideoError> {
    let mut text = String::new();
    if input.skip > 0 {
        // In microseconds, rounded up: the demuxer seeks to the last keyframe at or
        // before the in point, which must be frame `skip` itself, not one before.
        let micros = (input.skip as u64 * 1_000_000).div_ceil(u64::from(fps));
        text.push_str(&format!("inpoint {micros}us\n"));
    }
    let Some(take) = input.take else {
        return Ok(text);
    };
    let end = input.skip + take;
    // Probed once per file: many cuts of one file are usual (episodes kept from it).
    if !probed.contains_key(&input.path) {
        let packets = packets_in_decoding_order(&input.path)?;
        let mut times: Vec<f64> = packets.iter().map(|p| p.pts).collect();
        times.sort_by(f64::total_cmp);
        probed.insert(input.path.clone(), Probed { packets, times });
    }
    let Probed { packets, times } = &probed[&input.path];
    if end < packets.len() {
        let cut = cut_packet(packets, times, end).ok_or_else(|| VideoError::Failed {
            program: "concat".into(),
            path: input.path.clone(),
            message: format!(
                "frames before {end} refer to frames after it (B-frames), so the stream \
                 cannot end there by stream copy"
            ),
        })?;
        // Halfway between the last kept packet's decoding time and the cut's: the times
        // are printed rounded to microseconds, so the cut's own is not exact.
        let before = cut
            .checked_sub(1)
            .map_or(packets[cut].dts - 1.0, |b| packets[b].dts);
        let micros = ((before + packets[cut].dts) * 0.5e6).round() as i64;
        text.push_str(&format!("outpoint {micros}us\n"));
    }
    let duration = (take as f64 * 1e6 / f64::from(fps)).round() as u64;
    text.push_str(&format!("duration {duration}us\n"));
    Ok(text)
}

/// A file's packets in decoding order and their presentation times sorted.
struct Probed {
    packets: Vec<Packet>,
    times: Vec<f64>,
}

/// `end` when the stream can end after its first `end` packets in decoding order: those
/// are exactly the first `end` frames in presentation order (so no kept frame refers to
/// a dropped one). `None` where it cannot (B-frames decoded after the cut are presented
/// before it).
fn cut_packet(packets: &[Packet], times: &[f64], end: usize) -> Option<usize> {
    let last = packets[..end]
        .iter()
        .map(|p| p.pts)
        .fold(f64::NEG_INFINITY, f64::max);
    (last < times[end]).then_some(end)
}

/// Joins videos of one codec, size and frame rate `fps` into `out` by stream copy
/// (ffmpeg's concat demuxer): no re-encode, and the timestamps run on continuously, so
/// kept frame k of input i is at exactly (kept frames before input i + k) / fps. An
/// input's leading `skip` frames are cut (the demuxer's `inpoint`, at a keyframe, so the
/// cut is exact), and with a `take`, the frames after the kept ones (`outpoint`). (The demuxer offsets each input by its container duration, rounded to
/// milliseconds; the `setts` filter snaps every timestamp back onto the frame grid.)
/// Written to a temporary file beside `out` and renamed when complete.
pub fn concat_copy(inputs: &[ConcatInput], out: &Path, fps: u32) -> Result<(), VideoError> {
    let name = out
        .file_name()
        .map_or_else(|| "video".into(), |n| n.to_string_lossy().into_owned());
    let list = out.with_file_name(format!(".{name}.concat.txt"));
    let tmp = out.with_file_name(format!(".{name}.partial.mp4"));
    let mut text = String::from("ffconcat version 1.0\n");
    let mut probed = std::collections::HashMap::new();
    for input in inputs {
        let abs = std::path::absolute(&input.path).map_err(|source| VideoError::Io {
            path: input.path.clone(),
            source,
        })?;
        // The concat list quotes paths with single quotes; a quote is written as '\''.
        let quoted = abs.to_string_lossy().replace('\'', "'\\''");
        text.push_str(&format!("file '{quoted}'\n"));
        text.push_str(&concat_points(input, fps, &mut probed)?);
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
