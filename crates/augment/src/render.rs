//! Rendering a unit of work: replays of one episode drawn from one simulation (or, with
//! `--dynamics`, one replay on its own model copy), every replay's cameras streamed
//! frame by frame into its encoders (and depth archives), each worker thread keeping
//! one renderer.

use std::cell::RefCell;
use std::path::Path;
use std::sync::Arc;

use dexjoco_core::{Episode, FrameArray};
use dexjoco_formats::npz::DepthWriter;
use dexjoco_formats::raw;
use dexjoco_sim::mujoco_rs::prelude::MjModel;
use dexjoco_sim::{CameraView, EnvOptions, RenderSettings, Renderer, Scene, TaskEnv};
use dexjoco_video::{Codec, VideoSpec, VideoWriter};

use crate::config::{AugmentConfig, replay_name};
use crate::dynamics::{DynamicsValue, apply_dynamics, dynamics_seed, sample_dynamics};
use crate::error::{AugmentError, io_err, sim_err, video_err};
use crate::inputs::Source;
use crate::physics::{Physics, deviation, frames, new_env};
use crate::randomize::{VisualSample, apply_visuals};
use crate::report::ReplayRecord;
use crate::run::TaskAssets;
use crate::staging::{
    Outcome, commit_replay, replay_cameras, replay_episode, staging_dir, write_dropped,
};

thread_local! {
    /// One renderer per worker thread, for the scene it last drew.
    static RENDERER: RefCell<Option<(String, Renderer)>> = const { RefCell::new(None) };
}

fn with_renderer<T>(
    key: &str,
    model: &MjModel,
    settings: RenderSettings,
    f: impl FnOnce(&mut Renderer) -> Result<T, AugmentError>,
) -> Result<T, AugmentError> {
    RENDERER.with(|cell| {
        let mut slot = cell.borrow_mut();
        let fresh = !matches!(&*slot, Some((k, r)) if k == key && r.settings() == settings);
        if fresh {
            *slot = None;
            let r = Renderer::new(model, settings).map_err(sim_err(key))?;
            *slot = Some((key.to_owned(), r));
        }
        let (_, r) = slot.as_mut().expect("set");
        f(r)
    })
}

/// Closes this thread's renderer (and its EGL context).
pub(crate) fn close_renderer() {
    RENDERER.with(|cell| cell.borrow_mut().take());
}

/// One unit of rendering work: replays `replays` of one episode, from one simulation.
pub(crate) struct Unit {
    pub(crate) source: usize,
    pub(crate) replays: Vec<usize>,
}

/// A replay being written.
struct Pending {
    index: usize,
    staging: std::path::PathBuf,
    sample: VisualSample,
    writers: Vec<VideoWriter>,
    /// One per camera, in the order of `writers`, with `--depth`.
    depth: Vec<DepthWriter>,
    /// The drawn dynamics, with `--dynamics`.
    dynamics: Option<Vec<DynamicsValue>>,
    preview: Option<dexjoco_sim::Frame>,
}

/// Renders one unit and writes its replays (or, failed under `--dynamics`, their
/// records).
pub(crate) fn render_unit(
    unit: &Unit,
    src: &Source,
    assets: &TaskAssets,
    physics: &Physics,
    config: &AugmentConfig,
    out: &Path,
) -> Result<Vec<Outcome>, AugmentError> {
    let n = frames(src, config);
    let id = &src.episode.id;
    let ep_key = src.key();
    let fixed: Vec<(String, usize)> = config
        .cameras
        .iter()
        .map(|c| {
            assets
                .scene
                .camera_id(c)
                .map(|i| (c.clone(), i))
                .map_err(sim_err(id))
        })
        .collect::<Result<_, _>>()?;
    let cameras = replay_cameras(&config.cameras);
    let spec = VideoSpec {
        width: config.settings.width,
        height: config.settings.height,
        fps: src.episode.fps.round().max(1.0) as u32,
        codec: Codec::DEXJOCO,
    };
    let mut pending = Vec::new();
    for &r in &unit.replays {
        let staging = staging_dir(out, &src.spec.id, &replay_name(id, r));
        if staging.exists() {
            fs_err::remove_dir_all(&staging).map_err(io_err("remove", &staging))?;
        }
        let videos = staging.join(raw::VIDEOS);
        fs_err::create_dir_all(&videos).map_err(io_err("create", &videos))?;
        let seed = crate::randomize::replay_seed(config.seed, &ep_key, r);
        let sample = VisualSample::sample(seed, &assets.pool, &assets.table, assets.nlight);
        let dynamics = if config.dynamics {
            Some(sample_dynamics(
                &src.spec,
                &assets.scene.model,
                dynamics_seed(seed),
            )?)
        } else {
            None
        };
        let mut writers = Vec::new();
        let mut depth = Vec::new();
        for cam in &cameras {
            let w = VideoWriter::create(videos.join(format!("{cam}.mp4")), spec)
                .map_err(video_err(id))?;
            writers.push(w);
            if config.depth {
                depth.push(DepthWriter::create(
                    videos.join(format!("{cam}_depth.npz")),
                    n,
                    spec.width,
                    spec.height,
                )?);
            }
        }
        pending.push(Pending {
            index: r,
            staging,
            sample,
            writers,
            depth,
            dynamics,
            preview: None,
        });
    }

    // With --dynamics a unit holds one replay, simulated on its own model copy.
    let mut env = match pending.first().and_then(|p| p.dynamics.as_ref()) {
        Some(values) => {
            debug_assert_eq!(pending.len(), 1);
            let model = apply_dynamics(&src.spec, &assets.scene.model, values)?;
            let scene = Scene {
                model: Arc::new(model),
                path: assets.scene.path.clone(),
            };
            let state0 = src.episode.array(Episode::STATE).expect("checked").row(0);
            TaskEnv::from_initial_state(&scene, &src.spec, state0, EnvOptions::default())
                .map_err(sim_err(id))?
        }
        None => new_env(src, assets)?,
    };
    let actions = src.episode.array(Episode::ACTION).expect("checked");
    let mut rows = Vec::with_capacity(n);
    let mut first_success = None;
    with_renderer(
        &assets.key,
        &assets.scene.model,
        RenderSettings {
            depth: config.depth,
            ..config.settings
        },
        |renderer| {
            for k in 0..n {
                rows.push(env.state());
                for p in &mut pending {
                    let views = std::iter::once(p.sample.camera.view())
                        .chain(fixed.iter().map(|(_, i)| CameraView::Fixed(*i)));
                    for (c, (view, writer)) in views.zip(p.writers.iter_mut()).enumerate() {
                        renderer.update_scene(env.data_mut(), view);
                        apply_visuals(renderer, &p.sample, &assets.table);
                        let frame = renderer.draw().map_err(sim_err(id))?;
                        writer.write_frame(&frame.rgb).map_err(video_err(id))?;
                        if let (Some(d), Some(depth)) = (p.depth.get_mut(c), &frame.depth) {
                            d.write_frame(depth)?;
                        }
                        if k == 0 && p.preview.is_none() {
                            p.preview = Some(frame);
                        }
                    }
                }
                let v = env.step(actions.row(k)).map_err(sim_err(id))?;
                if v.success && first_success.is_none() {
                    first_success = Some(k);
                }
            }
            Ok(())
        },
    )?;
    let replayed = FrameArray::from_rows(&rows).map_err(|e| AugmentError::Input(e.to_string()))?;
    // Without --dynamics this simulation must be the validated one, bit for bit; with
    // it, this simulation is the replay's own, and says whether it succeeded.
    let (states, first_success, max_dev, dev_at) = if config.dynamics {
        let recorded = src.episode.array(Episode::STATE).expect("checked");
        let (d, at) = deviation(&replayed, recorded);
        (replayed, first_success, d, at)
    } else {
        if replayed
            .as_slice()
            .iter()
            .zip(physics.states.as_slice())
            .any(|(a, b)| a.to_bits() != b.to_bits())
        {
            return Err(AugmentError::Input(format!(
                "episode '{id}': the rendering simulation diverged from the validation one"
            )));
        }
        (
            physics.states.clone(),
            physics.first_success,
            physics.deviation,
            physics.deviation_at,
        )
    };
    let record_of = |index: usize,
                     sample: VisualSample,
                     dynamics: Option<Vec<DynamicsValue>>,
                     videos: Vec<String>,
                     depth: Vec<String>| ReplayRecord {
        name: replay_name(id, index),
        task: src.spec.id.clone(),
        episode: id.clone(),
        replay: index,
        sample,
        success: first_success.is_some(),
        first_success,
        steps: n,
        max_state_deviation: max_dev,
        deviation_at: dev_at,
        videos,
        depth,
        dynamics,
    };
    let mut outcomes = Vec::new();
    if config.dynamics && first_success.is_none() && !config.keep_failed {
        // The task failed under these dynamics: only the record of the draw is kept.
        for p in pending {
            for w in p.writers {
                let _ = w.finish();
            }
            let _ = fs_err::remove_dir_all(&p.staging);
            let record = record_of(p.index, p.sample, p.dynamics, Vec::new(), Vec::new());
            write_dropped(out, &record)?;
            tracing::debug!(episode = %id, replay = p.index, "failed under randomized dynamics; dropped");
            outcomes.push(Outcome::Dropped(record));
        }
        return Ok(outcomes);
    }
    for p in pending {
        for w in p.writers {
            w.finish().map_err(video_err(id))?;
        }
        for d in p.depth {
            d.finish()?;
        }
        let videos = cameras
            .iter()
            .map(|c| format!("{}/{c}.mp4", raw::VIDEOS))
            .collect();
        let depth = if config.depth {
            cameras
                .iter()
                .map(|c| format!("{}/{c}_depth.npz", raw::VIDEOS))
                .collect()
        } else {
            Vec::new()
        };
        let name = replay_name(id, p.index);
        let ep = replay_episode(src, &name, &states, &cameras, config.depth)?;
        let record = record_of(p.index, p.sample, p.dynamics, videos, depth);
        commit_replay(out, &p.staging, &ep, &record, p.preview.as_ref())?;
        outcomes.push(Outcome::Kept(record));
    }
    Ok(outcomes)
}
