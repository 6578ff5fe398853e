//! `--depth`: each output camera's depth archive (augment's `videos/<raw>_depth.npz`,
//! float32 (T, H, W) metres) joins the prepared episode as a [`DepthPart`]; for LeRobot
//! v3.0 its kept frames are quantized and encoded here, in parallel with the other
//! episodes, and measured (statistics in metres under `observation.images.<name>_depth`).

use std::path::Path;

use dexjoco_core::Location;
use dexjoco_formats::dataset::depth::{depth_key, encode_part};
use dexjoco_formats::dataset::{DepthPart, PreparedEpisode, VideoLayout};
use dexjoco_formats::npz::depth_npz_shape;
use dexjoco_formats::raw::VIDEOS;

use crate::config::Selection;
use crate::error::ConvertError;
use crate::prepare::{InputEpisode, camera_mapping};

/// Adds the depth parts of `p`'s cameras (in camera-name order). An archive that is
/// missing, unreadable, of another length than the episode or of another size than the
/// camera's video fails the episode, naming the file. With the `Joined` layout (LeRobot
/// v3.0) the kept frames are encoded into `work_dir` (named after `ordinal`).
pub fn add_depth(
    p: &mut PreparedEpisode,
    input: &InputEpisode,
    selection: &Selection,
    layout: VideoLayout,
    work_dir: &Path,
    ordinal: usize,
) -> Result<(), ConvertError> {
    let ep = &input.episode;
    let mut cameras = camera_mapping(ep, &selection.for_task(&ep.task).cameras);
    cameras.sort();
    let mut parts = Vec::new();
    for (name, raw) in cameras {
        let path = input.dir.join(VIDEOS).join(format!("{raw}_depth.npz"));
        let at = || {
            Location::episode(&ep.id)
                .field(format!("depth of camera {raw}"))
                .path(&path)
        };
        let bad = |message: String| ConvertError::Episode {
            at: at().into(),
            message,
        };
        if !path.is_file() {
            return Err(bad(
                "no depth archive (--depth needs replays made with augment --depth)".into(),
            ));
        }
        let (frames, height, width) = depth_npz_shape(&path).map_err(|e| bad(e.to_string()))?;
        if frames != ep.len() {
            return Err(bad(format!(
                "the archive has {frames} frames, the episode {}",
                ep.len()
            )));
        }
        if let Some(v) = p.videos.iter().find(|v| v.name == name)
            && (v.info.width as usize, v.info.height as usize) != (width, height)
        {
            return Err(bad(format!(
                "the archive's {width}x{height} frames differ from the {}x{} video",
                v.info.width, v.info.height
            )));
        }
        let mut part = DepthPart {
            name: name.clone(),
            path: path.clone(),
            skip: p.skipped,
            frames,
            width,
            height,
            video: None,
        };
        if layout == VideoLayout::Joined {
            let out = work_dir.join(format!("{ordinal:06}-{name}_depth.mp4"));
            let (video, stats) = encode_part(&p.id, &part, p.fps, &out)?;
            p.stats.insert(depth_key(&name), stats);
            part.video = Some(video);
        }
        parts.push(part);
    }
    p.depth = parts;
    Ok(())
}
