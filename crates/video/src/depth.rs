//! Depth streams as lerobot 0.6.1 stores them: 12-bit codes (0..4095) in a gray12le
//! HEVC video, lossless (`DepthEncoderConfig`: libx265, `x265-params lossless=1`, GOP 2).
//!
//! [`DepthVideoWriter`] streams frames of codes into ffmpeg; x265 runs on one thread
//! (`pools=1:frame-threads=1`) so the bytes do not depend on the machine's core count.
//! [`decode_gray12`] reads the codes back.

use std::path::{Path, PathBuf};
use std::process::Command;

use crate::{Codec, VideoError, VideoSpec, VideoWriter, decode_raw, ffmpeg_program};

/// The largest 12-bit code.
pub const DEPTH_CODE_MAX: u16 = 4095;

/// Streams frames of 12-bit depth codes into a lossless gray12le HEVC mp4.
#[derive(Debug)]
pub struct DepthVideoWriter {
    inner: VideoWriter,
    bytes: Vec<u8>,
}

impl DepthVideoWriter {
    /// Starts an encoder for `width` x `height` frames at `fps`, writing to a temporary
    /// file beside `path` (renamed by [`DepthVideoWriter::finish`]).
    pub fn create(
        path: impl Into<PathBuf>,
        width: u32,
        height: u32,
        fps: u32,
    ) -> Result<Self, VideoError> {
        let mut cmd = Command::new(ffmpeg_program());
        cmd.args(["-c:v", "libx265", "-g", "2"])
            .args([
                "-x265-params",
                "lossless=1:pools=1:frame-threads=1:log-level=error",
            ])
            .args(["-pix_fmt", "gray12le"]);
        let spec = VideoSpec {
            width,
            height,
            fps,
            // Not used by `start`; the encoder is given in `cmd`.
            codec: Codec::DEXJOCO,
        };
        let frame_bytes = width as usize * height as usize * 2;
        Ok(Self {
            inner: VideoWriter::start(path.into(), spec, "gray12le", frame_bytes, cmd)?,
            bytes: Vec::with_capacity(frame_bytes),
        })
    }

    /// Appends one frame of codes (rows top to bottom, each at most 4095).
    pub fn write_codes(&mut self, codes: &[u16]) -> Result<(), VideoError> {
        self.bytes.clear();
        for c in codes {
            self.bytes
                .extend_from_slice(&(*c).min(DEPTH_CODE_MAX).to_le_bytes());
        }
        self.inner.write_frame(&self.bytes)
    }

    /// Frames written so far.
    pub fn frames(&self) -> usize {
        self.inner.frames()
    }

    /// Closes the stream, waits for ffmpeg and moves the file into place; returns the
    /// number of frames.
    pub fn finish(self) -> Result<usize, VideoError> {
        self.inner.finish()
    }
}

/// Decodes every frame of a gray12le video to its 12-bit codes, one `Vec` per frame.
pub fn decode_gray12(path: &Path) -> Result<Vec<Vec<u16>>, VideoError> {
    let (raw, size) = decode_raw(path, "gray12le", 2)?;
    Ok(raw
        .chunks_exact(size)
        .map(|f| {
            f.chunks_exact(2)
                .map(|b| u16::from_le_bytes([b[0], b[1]]))
                .collect()
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_survive_the_lossless_stream() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("d.mp4");
        let (w, h) = (32u32, 16u32);
        let frames: Vec<Vec<u16>> = (0..5u16)
            .map(|k| {
                (0..w * h)
                    .map(|i| (i as u16 * 37 + k * 911) % 4096)
                    .collect()
            })
            .collect();
        let mut writer = DepthVideoWriter::create(&path, w, h, 10).unwrap();
        for f in &frames {
            writer.write_codes(f).unwrap();
        }
        assert!(writer.write_codes(&[0; 3]).is_err(), "a short frame fails");
        drop(writer);
        assert!(!path.exists(), "an unfinished stream leaves nothing");
        let mut writer = DepthVideoWriter::create(&path, w, h, 10).unwrap();
        for f in &frames {
            writer.write_codes(f).unwrap();
        }
        assert_eq!(writer.finish().unwrap(), 5);
        let info = crate::probe(&path).unwrap();
        assert_eq!(
            (info.codec.as_str(), info.pix_fmt.as_str()),
            ("hevc", "gray12le")
        );
        assert_eq!(decode_gray12(&path).unwrap(), frames);
    }
}
