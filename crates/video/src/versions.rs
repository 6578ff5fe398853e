//! The versions of the encoder programs that decide a video's bytes: ffmpeg as
//! `ffmpeg -version` names itself, and x264 as the encoder writes itself into the stream
//! it makes (a static ffmpeg on a cluster node links another x264 than Debian's, and
//! encodes other bytes from the same frames).

use std::io::Write;
use std::process::{Command, Stdio};

use serde::{Deserialize, Serialize};

use crate::{VideoError, ffmpeg_program};

/// What the version probe names in its errors (it writes no file).
const PROBE: &str = "<encoder version probe>";

/// The encoder's versions.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct EncoderVersions {
    /// ffmpeg's version, the word after `ffmpeg version` (e.g. `5.1.9-0+deb12u1`).
    pub ffmpeg: String,
    /// x264's identity as it writes it into an H.264 stream (e.g.
    /// `x264 - core 164 r3095 baee400`).
    pub x264: String,
}

/// Asks the ffmpeg this process encodes with ([`ffmpeg_program`]) for its version, and
/// encodes one 16x16 frame with libx264 to read x264's own.
pub fn encoder_versions() -> Result<EncoderVersions, VideoError> {
    let program = ffmpeg_program();
    let spawn_err = |source| VideoError::Spawn {
        program: program.display().to_string(),
        path: PROBE.into(),
        source,
    };
    let failed = |message: String| VideoError::Failed {
        program: program.display().to_string(),
        path: PROBE.into(),
        message,
    };
    let out = Command::new(&program)
        .arg("-version")
        .output()
        .map_err(spawn_err)?;
    let text = String::from_utf8_lossy(&out.stdout);
    let ffmpeg = text
        .lines()
        .next()
        .and_then(|l| l.strip_prefix("ffmpeg version "))
        .and_then(|rest| rest.split_whitespace().next())
        .ok_or_else(|| failed(format!("`-version` printed no version: {text:.200}")))?
        .to_owned();
    let mut child = Command::new(&program)
        .args(["-hide_banner", "-loglevel", "error", "-nostdin"])
        .args([
            "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", "16x16", "-i", "-",
        ])
        .args(["-frames:v", "1", "-c:v", "libx264", "-threads", "1"])
        .args(["-pix_fmt", "yuv420p", "-f", "h264", "-"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(spawn_err)?;
    let fed = child
        .stdin
        .take()
        .expect("piped")
        .write_all(&[0; 16 * 16 * 3]);
    let out = child.wait_with_output().map_err(spawn_err)?;
    if fed.is_err() || !out.status.success() {
        return Err(failed(format!(
            "encoding one frame with libx264 failed: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    let x264 = x264_identity(&out.stdout)
        .ok_or_else(|| failed("libx264 wrote no version into its stream".into()))?;
    Ok(EncoderVersions { ffmpeg, x264 })
}

/// x264's identity in an H.264 stream: `x264 - core N rM hash`, from the user-data SEI
/// it writes before the first frame.
fn x264_identity(stream: &[u8]) -> Option<String> {
    let marker = b"x264 - core ";
    let start = stream.windows(marker.len()).position(|w| w == marker)?;
    let rest = &stream[start..];
    // The identity ends where its description starts (` - H.264/MPEG-4 AVC codec`).
    let end = marker.len() + rest[marker.len()..].windows(3).position(|w| w == b" - ")?;
    Some(String::from_utf8_lossy(&rest[..end]).into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn x264_names_itself_up_to_its_description() {
        let sei =
            b"\0\0\x01\x06\x05x264 - core 164 r3095 baee400 - H.264/MPEG-4 AVC codec - Copyleft";
        assert_eq!(
            x264_identity(sei).as_deref(),
            Some("x264 - core 164 r3095 baee400")
        );
        assert_eq!(x264_identity(b"no encoder here"), None);
    }

    #[test]
    fn the_installed_ffmpeg_reports_both_versions() {
        let v = encoder_versions().unwrap();
        assert!(!v.ffmpeg.is_empty() && !v.ffmpeg.contains(' '), "{v:?}");
        assert!(v.x264.starts_with("x264 - core "), "{v:?}");
    }
}
