//! Depth in the datasets, from augment's `videos/<camera>_depth.npz` (float32 metres):
//!
//! - LeRobot v3.0, as lerobot 0.6.1 stores depth: a video feature
//!   `observation.images.<camera>_depth` of shape (H, W, 1) whose `info` has
//!   `is_depth_map: true`, `depth_unit: "m"` and the quantizer's `video.depth_min`,
//!   `video.depth_max`, `video.shift`, `video.use_log`; frames quantized to 12-bit codes
//!   by [`quantize`] (lerobot's `quantize_depth`, logarithmic, 0.01..10 m, shift 3.5 m)
//!   and encoded lossless into gray12le HEVC ([`encode_part`]); statistics in metres,
//!   sampled as for images but not divided by 255, one channel ([`DepthSampler`]).
//! - Diffusion Policy: the metres themselves, `data/<camera>_depth` float32 (T, H, W)
//!   (in `diffusion_policy`).

use std::collections::BTreeMap;
use std::path::Path;

use dexjoco_core::Location;
use dexjoco_video::{DepthVideoWriter, VideoError};
use serde::Serialize;

use super::stats::{FeatureStats, column_stats, downsample_stride, sample_indices};
use super::{DepthPart, VideoPart};
use crate::error::{DatasetError, FormatError};
use crate::npz::for_each_depth_frame;

/// Depth (metres) at code 0 (lerobot's `DEFAULT_DEPTH_MIN`).
pub const DEPTH_MIN: f64 = 0.01;
/// Depth (metres) at code 4095 (`DEFAULT_DEPTH_MAX`).
pub const DEPTH_MAX: f64 = 10.0;
/// Shift (metres) added before the logarithm (`DEFAULT_DEPTH_SHIFT`).
pub const DEPTH_SHIFT: f64 = 3.5;
/// The largest code (12 bits).
pub const DEPTH_QMAX: u16 = 4095;
/// Codec of the depth videos, as ffprobe and lerobot name it.
pub const DEPTH_CODEC: &str = "hevc";
/// Pixel format of the depth videos.
pub const DEPTH_PIX_FMT: &str = "gray12le";

/// The feature key of camera `name`'s depth: `observation.images.<name>_depth`.
pub fn depth_key(name: &str) -> String {
    format!("observation.images.{name}_depth")
}

/// lerobot 0.6.1's `quantize_depth` of one float32 value in metres, with its default
/// parameters: the arithmetic is float32 as numpy does it (`log(d + shift)`, minus
/// `log(depth_min + shift)`, over the log range, times 4095, rounded half to even, clipped
/// to 0..4095; NaN gives 0). The logarithm is the correctly rounded one; numpy's SIMD
/// float32 logarithm can differ from it by one unit in the last place, which moves a
/// value lying within about 1e-4 of a rounding boundary to the neighbouring code.
pub fn quantize(depth: f32) -> u16 {
    let shift = DEPTH_SHIFT as f32;
    let log_min = (f64::from(DEPTH_MIN as f32 + shift)).ln();
    let log_max = (f64::from(DEPTH_MAX as f32 + shift)).ln();
    let log = f64::from(depth + shift).ln() as f32;
    let norm = (log - log_min as f32) / (log_max - log_min) as f32;
    let q = (norm * f32::from(DEPTH_QMAX))
        .round_ties_even()
        .clamp(0.0, f32::from(DEPTH_QMAX));
    if q.is_nan() { 0 } else { q as u16 }
}

/// lerobot 0.6.1's `dequantize_depth` of one code, in metres (float32, clipped to
/// `DEPTH_MIN..DEPTH_MAX`).
pub fn dequantize(code: u16) -> f32 {
    let log_min = (DEPTH_MIN + DEPTH_SHIFT).ln();
    let log_max = (DEPTH_MAX + DEPTH_SHIFT).ln();
    let scale = (log_max - log_min) / f64::from(DEPTH_QMAX);
    let v = (f32::from(code) * scale as f32 + log_min as f32).exp() - DEPTH_SHIFT as f32;
    v.clamp(DEPTH_MIN as f32, DEPTH_MAX as f32)
}

/// Accumulates the sampled depth frames of one camera of one episode, as lerobot's
/// `compute_episode_stats` does for a depth map: strided like images, values as stored
/// (metres, no division by 255), one channel.
#[derive(Debug, Default)]
pub struct DepthSampler {
    values: Vec<f64>,
    frames: u64,
}

impl DepthSampler {
    /// Adds one frame (row-major, metres).
    pub fn add_frame(&mut self, depth: &[f32], width: usize, height: usize) {
        let s = downsample_stride(width as u32, height as u32);
        for y in (0..height).step_by(s) {
            for x in (0..width).step_by(s) {
                self.values.push(f64::from(depth[y * width + x]));
            }
        }
        self.frames += 1;
    }

    /// Statistics of the sampled values, count = sampled frames; None without frames.
    pub fn finish(self) -> Option<FeatureStats> {
        if self.frames == 0 {
            return None;
        }
        let mut s = column_stats(&self.values, 1);
        s.count = self.frames;
        Some(s)
    }
}

/// Why streaming a depth archive into a video stopped.
enum Stop {
    Format(FormatError),
    Video(VideoError),
}

impl From<FormatError> for Stop {
    fn from(e: FormatError) -> Self {
        Self::Format(e)
    }
}

/// Quantizes and encodes the kept frames of `part`'s archive (from frame `part.skip`)
/// into `out` (12-bit gray HEVC, lossless, GOP 2, at `fps`), sampling them for statistics
/// as lerobot does; returns the video part (a temporary file, named
/// `<camera>_depth`) and the statistics in metres.
pub fn encode_part(
    id: &str,
    part: &DepthPart,
    fps: u32,
    out: &Path,
) -> Result<(VideoPart, FeatureStats), DatasetError> {
    let at = || {
        Location::episode(id)
            .field(format!("depth of camera {}", part.name))
            .path(&part.path)
    };
    let video_err = |source: VideoError| DatasetError::Video {
        at: at().into(),
        source: source.into(),
    };
    let (w, h) = (part.width, part.height);
    let kept = part.frames.saturating_sub(part.skip);
    let mut samples = sample_indices(kept).into_iter().peekable();
    let mut sampler = DepthSampler::default();
    let mut writer = DepthVideoWriter::create(out, w as u32, h as u32, fps).map_err(video_err)?;
    let mut codes = vec![0u16; w * h];
    let streamed = for_each_depth_frame(&part.path, |k, frame| {
        if frame.len() != w * h {
            return Err(Stop::Format(FormatError::Io {
                op: "read",
                path: part.path.clone(),
                source: std::io::Error::other(format!(
                    "frame {k} has {} values, expected {w}x{h}",
                    frame.len()
                )),
            }));
        }
        if k < part.skip {
            return Ok(());
        }
        for (c, d) in codes.iter_mut().zip(frame) {
            *c = quantize(*d);
        }
        writer.write_codes(&codes).map_err(Stop::Video)?;
        if samples.next_if_eq(&(k - part.skip)).is_some() {
            sampler.add_frame(frame, w, h);
            while samples.next_if_eq(&(k - part.skip)).is_some() {}
        }
        Ok(())
    });
    match streamed {
        Err(Stop::Video(e)) => return Err(video_err(e)),
        Err(Stop::Format(e)) => {
            return Err(DatasetError::Episode {
                at: at().into(),
                message: e.to_string(),
            });
        }
        Ok((t, _, _)) if t != part.frames => {
            return Err(DatasetError::Episode {
                at: at().into(),
                message: format!("the archive has {t} frames, expected {}", part.frames),
            });
        }
        Ok(_) => {}
    }
    writer.finish().map_err(video_err)?;
    let info = dexjoco_video::probe(out).map_err(video_err)?;
    let video = VideoPart {
        name: format!("{}_depth", part.name),
        path: out.to_path_buf(),
        temporary: true,
        skip: 0,
        frames: kept,
        bytes: fs_err::metadata(out)?.len(),
        info,
        copied: false,
        reencoded_frames: 0,
        source: part.path.clone(),
    };
    let stats = sampler.finish().ok_or_else(|| DatasetError::Episode {
        at: at().into(),
        message: "no frame is kept".into(),
    })?;
    Ok((video, stats))
}

/// A depth video feature's `info`, with the keys and values lerobot 0.6.1 writes for a
/// depth camera recorded as float32 metres (`get_video_info` with a `DepthEncoderConfig`
/// on top of `{"is_depth_map": true, "depth_unit": "m"}`), in its order.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DepthVideoMeta {
    /// Always true: lerobot's `meta.depth_keys` lists the feature.
    pub is_depth_map: bool,
    /// The stored unit of the statistics, `m` (frames are returned in mm by default).
    pub depth_unit: &'static str,
    /// Frame height.
    #[serde(rename = "video.height")]
    pub height: u32,
    /// Frame width.
    #[serde(rename = "video.width")]
    pub width: u32,
    /// `hevc`.
    #[serde(rename = "video.codec")]
    pub codec: &'static str,
    /// `gray12le`.
    #[serde(rename = "video.pix_fmt")]
    pub pix_fmt: &'static str,
    /// Frames per second.
    #[serde(rename = "video.fps")]
    pub fps: u32,
    /// 1.
    #[serde(rename = "video.channels")]
    pub channels: u32,
    /// false.
    pub has_audio: bool,
    /// GOP size, 2.
    #[serde(rename = "video.g")]
    pub g: u32,
    /// lerobot's recorded CRF (30; x265's lossless mode ignores it).
    #[serde(rename = "video.crf")]
    pub crf: u32,
    /// null (x265's default preset).
    #[serde(rename = "video.preset")]
    pub preset: Option<String>,
    /// 0.
    #[serde(rename = "video.fast_decode")]
    pub fast_decode: u32,
    /// `pyav`, as lerobot records it.
    #[serde(rename = "video.video_backend")]
    pub video_backend: &'static str,
    /// `{"x265-params": "lossless=1"}`.
    #[serde(rename = "video.extra_options")]
    pub extra_options: BTreeMap<String, String>,
    /// Depth at code 0, metres.
    #[serde(rename = "video.depth_min")]
    pub depth_min: f64,
    /// Depth at code 4095, metres.
    #[serde(rename = "video.depth_max")]
    pub depth_max: f64,
    /// Shift before the logarithm, metres.
    #[serde(rename = "video.shift")]
    pub shift: f64,
    /// true: logarithmic quantization.
    #[serde(rename = "video.use_log")]
    pub use_log: bool,
}

impl DepthVideoMeta {
    /// The `info` of a depth feature of `width` x `height` at `fps`.
    pub fn new(width: u32, height: u32, fps: u32) -> Self {
        Self {
            is_depth_map: true,
            depth_unit: "m",
            height,
            width,
            codec: DEPTH_CODEC,
            pix_fmt: DEPTH_PIX_FMT,
            fps,
            channels: 1,
            has_audio: false,
            g: 2,
            crf: 30,
            preset: None,
            fast_decode: 0,
            video_backend: "pyav",
            extra_options: BTreeMap::from([("x265-params".to_owned(), "lossless=1".to_owned())]),
            depth_min: DEPTH_MIN,
            depth_max: DEPTH_MAX,
            shift: DEPTH_SHIFT,
            use_log: true,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_span_the_range_and_invert() {
        assert_eq!(quantize(0.01), 0);
        assert_eq!(quantize(0.0), 0);
        assert_eq!(quantize(10.0), DEPTH_QMAX);
        assert_eq!(quantize(50.0), DEPTH_QMAX);
        assert_eq!(quantize(f32::NAN), 0);
        for d in [0.3f32, 0.8, 1.5, 4.0] {
            let back = dequantize(quantize(d));
            // Half a code step of the log scale, relative to d + shift.
            let tol = (d + 3.5) * 1.7e-4;
            assert!((back - d).abs() <= tol, "{d} -> {back}");
        }
    }

    #[test]
    fn encoded_parts_start_at_the_first_kept_frame() {
        let dir = tempfile::tempdir().unwrap();
        let npz = dir.path().join("front_depth.npz");
        let (w, h, t) = (32usize, 32usize, 5usize);
        let frame = |k: usize| -> Vec<f32> {
            (0..w * h)
                .map(|i| 0.2 + 0.5 * k as f32 + 0.003 * i as f32)
                .collect()
        };
        let mut writer = crate::npz::DepthWriter::create(&npz, t, w as u32, h as u32).unwrap();
        for k in 0..t {
            writer.write_frame(&frame(k)).unwrap();
        }
        writer.finish().unwrap();
        let part = DepthPart {
            name: "front".into(),
            path: npz,
            skip: 2,
            frames: t,
            width: w,
            height: h,
            video: None,
        };
        let out = dir.path().join("d.mp4");
        let (video, stats) = encode_part("ep", &part, 30, &out).unwrap();
        assert_eq!((video.name.as_str(), video.frames), ("front_depth", 3));
        let codes = dexjoco_video::decode_gray12(&out).unwrap();
        assert_eq!(codes.len(), 3);
        for (j, c) in codes.iter().enumerate() {
            let want: Vec<u16> = frame(j + 2).iter().map(|d| quantize(*d)).collect();
            assert_eq!(c, &want, "kept frame {j}");
        }
        // Statistics of the kept frames, in metres.
        assert_eq!(stats.count, 3);
        assert!((stats.min[0] - f64::from(frame(2)[0])).abs() < 1e-9);
        assert!((stats.max[0] - f64::from(frame(4)[w * h - 1])).abs() < 1e-9);
    }
}
