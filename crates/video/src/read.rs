//! Reading videos back through ffmpeg: whole ([`decode_rgb`], and raw frames in any
//! pixel format for the depth videos) or streamed a frame at a time ([`VideoReader`]).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use crate::{VideoError, ffmpeg_program, probe, run, spawn_ffmpeg};

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
