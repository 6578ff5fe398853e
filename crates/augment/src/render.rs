//! Rendering a unit of work: replays of one episode drawn from one simulation (or, with
//! `--dynamics`, one replay on its own model copy), every replay's cameras streamed
//! frame by frame into its encoders (and depth archives). Each worker (thread or
//! process) keeps one renderer. The same code runs in-process and in worker processes.

use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use dexjoco_formats::SourceKind;
use dexjoco_formats::npz::DepthWriter;
use dexjoco_formats::raw;
use dexjoco_render::{RenderSettings, Renderer, RendererKind};
use dexjoco_sim::Scene;
use dexjoco_sim::mujoco_rs::prelude::MjModel;
use dexjoco_video::{VideoSpec, VideoWriter};
use serde::{Deserialize, Serialize};

use crate::assets::TaskAssets;
use crate::checks::ReplayChecks;
use crate::checks::inject::{Defects, ReplayDefects};
use crate::config::{AugmentConfig, replay_name};
use crate::error::{AugmentError, io_err, sim_err, video_err};
use crate::inputs::Source;
use crate::physics::{Physics, PhysicsSummary, new_env, replay};
use crate::profile::{EncoderClock, StageTimes, timed};
use crate::report::ReplayRecord;
use crate::staging::{
    Outcome, commit_replay, replay_cameras, replay_episode, staging_dir, write_dropped,
};
use dexjoco_render::randomize::{VisualSample, apply_visuals};
use dexjoco_sim::dynamics::{DynamicsValue, apply_dynamics, dynamics_seed, sample_dynamics};

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

/// Creates this thread's renderer for a task's scene (its textures uploaded), tells
/// `opened` which EGL device it drew on, and draws a few randomized views of the scene's
/// initial state, so that the first unit of the task finds the driver's shaders compiled
/// (llvmpipe compiles them on first use, seconds per process). Nothing is written; outputs
/// do not depend on it.
pub(crate) fn preload_renderer(
    assets: &TaskAssets,
    config: &AugmentConfig,
    opened: &mut dyn FnMut(&str),
) -> Result<(), AugmentError> {
    const WARM_UP_VIEWS: usize = 3;
    if config.renderer == RendererKind::Warp {
        return crate::warp::preload(assets, config, opened);
    }
    let model = &assets.scene.model;
    let mut data = dexjoco_sim::mujoco_rs::prelude::MjData::new(model.clone());
    data.forward();
    with_renderer(
        &assets.key,
        model,
        config.unit_render_settings(),
        |renderer| {
            let device = renderer.device();
            opened(&format!("EGL device {} ({})", device.index, device.label()));
            for r in 0..WARM_UP_VIEWS {
                let sample = assets.sample(config.seed, "warm-up", r);
                renderer.update_scene(&mut data, sample.camera.view());
                apply_visuals(renderer, &sample, &assets.table);
                renderer.draw().map_err(sim_err(&assets.key))?;
            }
            Ok(())
        },
    )
}

/// Whether this thread's renderer is open for `assets`' scene with `config`'s settings
/// (and has drawn: it is only kept after its warm-up or a unit).
pub(crate) fn renderer_ready(assets: &TaskAssets, config: &AugmentConfig) -> bool {
    if config.renderer == RendererKind::Warp {
        return crate::warp::ready(assets, config);
    }
    let settings = config.unit_render_settings();
    RENDERER.with(|cell| {
        matches!(&*cell.borrow(), Some((k, r)) if *k == assets.key && r.settings() == settings)
    })
}

/// Closes this thread's renderers (the EGL context, the Warp worker).
pub(crate) fn close_renderer() {
    RENDERER.with(|cell| cell.borrow_mut().take());
    crate::warp::close();
}

/// One unit of rendering work: replays of one episode, from one simulation; what a
/// worker process is sent.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct UnitJob {
    /// The episode's file or folder.
    pub(crate) path: PathBuf,
    /// Its kind.
    pub(crate) kind: SourceKind,
    /// Task id.
    pub(crate) task: String,
    /// Episode id.
    pub(crate) episode: String,
    /// Replay indices.
    pub(crate) replays: Vec<usize>,
    /// The validated simulation the rendering must reproduce (without `--dynamics`).
    pub(crate) physics: PhysicsSummary,
    /// Content hash of the source episode (recorded in each replay).
    pub(crate) source_hash: String,
    /// 0 for the first try, 1 for the retry.
    pub(crate) attempt: u32,
}

impl UnitJob {
    /// `<task>/<episode>`, the key of its replays' seeds.
    pub(crate) fn key(&self) -> String {
        format!("{}/{}", self.task, self.episode)
    }

    /// Frames this unit renders (all cameras, all replays), as planned.
    pub(crate) fn frames(&self, cameras: usize) -> u64 {
        (self.physics.frames * cameras * self.replays.len()) as u64
    }

    /// Removes what an interrupted attempt left in staging.
    pub(crate) fn clear_staging(&self, out: &Path) {
        for &r in &self.replays {
            let dir = staging_dir(out, &self.task, &replay_name(&self.episode, r));
            let _ = fs_err::remove_dir_all(dir);
        }
    }
}

/// A replay being written.
struct Pending {
    index: usize,
    staging: PathBuf,
    sample: VisualSample,
    writers: Vec<VideoWriter>,
    /// One per camera, in the order of `writers`, with `--depth`.
    depth: Vec<DepthWriter>,
    /// The drawn dynamics, with `--dynamics`.
    dynamics: Option<Vec<DynamicsValue>>,
    preview: Option<dexjoco_render::Frame>,
    /// The render checks watching its frames.
    checks: ReplayChecks,
    /// What the test hook corrupts (nothing unless it is set).
    defects: ReplayDefects,
}

/// What the unit needs besides the job: the episode, its task's scene and looks.
pub(crate) struct UnitInputs<'a> {
    pub(crate) src: &'a Source,
    pub(crate) assets: &'a TaskAssets,
    pub(crate) config: &'a AugmentConfig,
    pub(crate) out: &'a Path,
}

/// Renders one unit and writes its replays (or, failed under `--dynamics`, their
/// records), and says where its time went; `frames_done` is told every rendered frame
/// count as it happens (and with 0 before each replay is committed): an error from it (the
/// run that asked for the unit has ended) stops the unit before anything more is written.
pub(crate) fn render_unit(
    job: &UnitJob,
    inputs: &UnitInputs<'_>,
    frames_done: &mut dyn FnMut(u64) -> Result<(), AugmentError>,
) -> Result<(Vec<Outcome>, StageTimes), AugmentError> {
    let UnitInputs {
        src,
        assets,
        config,
        ..
    } = *inputs;
    let id = &src.episode.id;
    let fixed = assets.fixed_cameras(&config.cameras, id)?;
    let cameras = replay_cameras(&config.cameras);
    let mut times = StageTimes::default();
    let encoders = EncoderClock::start();

    let (scene, expected) = match simulation_to_render(job, inputs, &mut times, frames_done)? {
        ToRender::Simulation(scene, expected) => (scene, expected),
        ToRender::Dropped(record) => return Ok((vec![Outcome::Dropped(*record)], times)),
    };
    let mut pending = open_replays(job, inputs, &cameras, expected.frames)?;
    let (rendered, renderer) = draw_replays(
        inputs,
        &scene,
        &fixed,
        cameras.len(),
        &mut pending,
        &mut times,
        frames_done,
    )?;
    // The rendering simulation must be the validated one, bit for bit.
    if rendered.summary != expected {
        return Err(AugmentError::Input(format!(
            "episode '{id}': the rendering simulation diverged from the validation one \
             ({} frames, first success {:?}; validated: {} frames, first success {:?})",
            rendered.summary.frames,
            rendered.summary.first_success,
            expected.frames,
            expected.first_success
        )));
    }
    let outcomes = commit_replays(
        job,
        inputs,
        pending,
        (&rendered, &renderer),
        &expected,
        &cameras,
        &mut times,
        frames_done,
    )?;
    times.encode_cpu = encoders.seconds();
    Ok((outcomes, times))
}

/// What a unit renders: a simulation and the physics it must reproduce, or nothing but the
/// record of a draw under which the task failed (`--dynamics`).
enum ToRender {
    Simulation(Scene, PhysicsSummary),
    Dropped(Box<ReplayRecord>),
}

/// The simulation to render: the validated one, or with --dynamics the replay's own on
/// a model copy (one replay per unit), simulated first so a failed draw is not rendered
/// (its record is written instead).
fn simulation_to_render(
    job: &UnitJob,
    inputs: &UnitInputs<'_>,
    times: &mut StageTimes,
    frames_done: &mut dyn FnMut(u64) -> Result<(), AugmentError>,
) -> Result<ToRender, AugmentError> {
    let UnitInputs {
        src,
        assets,
        config,
        out,
    } = *inputs;
    if !config.dynamics {
        return Ok(ToRender::Simulation(
            assets.scene.clone(),
            job.physics.clone(),
        ));
    }
    let id = &src.episode.id;
    let ep_key = job.key();
    let r = job.replays[0];
    let seed = dexjoco_render::randomize::replay_seed(config.seed, &ep_key, r);
    let values = sample_dynamics(&src.spec, &assets.scene.model, dynamics_seed(seed))?;
    let model = apply_dynamics(&src.spec, &assets.scene.model, &values)?;
    let scene = Scene {
        model: Arc::new(model),
        path: assets.scene.path.clone(),
    };
    let mut env = new_env(src, &scene, &src.spec)?;
    let physics = timed(&mut times.physics, || {
        replay(src, &mut env, config, |_, _| Ok(()))
    })?;
    if physics.summary.first_success.is_none() && !config.keep_failed {
        // The task failed under these dynamics: only the record of the draw is kept.
        let sample = assets.sample(config.seed, &ep_key, r);
        let record = record_of(job, r, sample, Some(values), &physics.summary);
        frames_done(0)?;
        write_dropped(out, &record)?;
        tracing::debug!(episode = %id, replay = r, "failed under randomized dynamics; dropped");
        return Ok(ToRender::Dropped(Box::new(record)));
    }
    Ok(ToRender::Simulation(scene, physics.summary))
}

/// Opens each replay of the unit in a fresh staging folder: its randomization (and drawn
/// dynamics) and a video writer (and depth writer) per camera, for `n` frames.
fn open_replays(
    job: &UnitJob,
    inputs: &UnitInputs<'_>,
    cameras: &[String],
    n: usize,
) -> Result<Vec<Pending>, AugmentError> {
    let UnitInputs {
        src,
        assets,
        config,
        out,
    } = *inputs;
    let id = &src.episode.id;
    let ep_key = job.key();
    let spec = VideoSpec {
        width: config.settings.width,
        height: config.settings.height,
        fps: src.episode.fps.round().max(1.0) as u32,
        codec: config.video.codec(),
    };
    // Keyframes where convert may cut the static leading frames, so it cuts by stream copy.
    let keyframes = config
        .video
        .keyframes(dexjoco_core::possible_cuts(&src.episode));
    let defects = Defects::from_env()?;
    let mut pending = Vec::new();
    for &r in &job.replays {
        let staging = staging_dir(out, &src.spec.id, &replay_name(id, r));
        if staging.exists() {
            fs_err::remove_dir_all(&staging).map_err(io_err("remove", &staging))?;
        }
        let videos = staging.join(raw::VIDEOS);
        fs_err::create_dir_all(&videos).map_err(io_err("create", &videos))?;
        let seed = dexjoco_render::randomize::replay_seed(config.seed, &ep_key, r);
        let sample = assets.sample(config.seed, &ep_key, r);
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
        for cam in cameras {
            let w = VideoWriter::create_with(videos.join(format!("{cam}.mp4")), spec, &keyframes)
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
            checks: ReplayChecks::new(cameras, spec.width),
            defects: defects.for_replay(&src.spec.id, &replay_name(id, r), cameras),
        });
    }
    Ok(pending)
}

/// Replays the episode on `scene` with this thread's renderer, drawing every pending
/// replay's `cameras` views of each step into its writers; returns the simulation and
/// the renderer's name for the records.
fn draw_replays(
    inputs: &UnitInputs<'_>,
    scene: &Scene,
    fixed: &[usize],
    cameras: usize,
    pending: &mut [Pending],
    times: &mut StageTimes,
    frames_done: &mut dyn FnMut(u64) -> Result<(), AugmentError>,
) -> Result<(Physics, String), AugmentError> {
    if inputs.config.renderer == RendererKind::Warp {
        let id = &inputs.src.episode.id;
        let samples: Vec<VisualSample> = pending.iter().map(|p| p.sample.clone()).collect();
        let source = crate::warp::Source {
            src: inputs.src,
            assets: inputs.assets,
            config: inputs.config,
            scene,
            fixed,
        };
        return crate::warp::draw_replays(
            &source,
            &samples,
            times,
            &mut |r, c, k, frame, times| pending[r].take(id, c, k, frame, times),
            frames_done,
        );
    }
    let UnitInputs {
        src,
        assets,
        config,
        ..
    } = *inputs;
    let id = &src.episode.id;
    let mut env = new_env(src, scene, &src.spec)?;
    let per_step = (cameras * pending.len()) as u64;
    with_renderer(
        &assets.key,
        &assets.scene.model,
        config.unit_render_settings(),
        |renderer| {
            // What the renderer did before this unit (a warm-up, another unit) is not ours.
            renderer.take_times();
            let started = Instant::now();
            let mut drawing = 0.0;
            let physics = replay(src, &mut env, config, |env, k| {
                let step_started = Instant::now();
                for p in pending.iter_mut() {
                    let views: Vec<_> = p.sample.views(fixed).collect();
                    for (c, view) in views.into_iter().enumerate() {
                        renderer.update_scene(env.data_mut(), view);
                        timed(&mut times.scene, || {
                            apply_visuals(renderer, &p.sample, &assets.table)
                        });
                        let frame = renderer.draw().map_err(sim_err(id))?;
                        p.take(id, c, k, frame, times)?;
                    }
                }
                let r = frames_done(per_step);
                drawing += step_started.elapsed().as_secs_f64();
                r
            });
            times.physics += started.elapsed().as_secs_f64() - drawing;
            times.add_render(&renderer.take_times());
            Ok((physics?, "opengl".to_owned()))
        },
    )
}

impl Pending {
    /// Takes camera `c`'s frame of step `k`: the test hook's defects, the render checks,
    /// the encoder (and depth archive), the preview.
    fn take(
        &mut self,
        id: &str,
        c: usize,
        k: usize,
        mut frame: dexjoco_render::Frame,
        times: &mut StageTimes,
    ) -> Result<(), AugmentError> {
        self.defects.frame(c, k, &mut frame);
        timed(&mut times.checks, || {
            self.checks.frame(c, k, &frame.rgb, frame.depth.as_deref());
        });
        let writer = &mut self.writers[c];
        timed(&mut times.encode_feed, || writer.write_frame(&frame.rgb)).map_err(video_err(id))?;
        if let (Some(d), Some(depth)) = (self.depth.get_mut(c), &frame.depth) {
            d.write_frame(depth)?;
        }
        if k == 0 && self.preview.is_none() {
            self.preview = Some(frame);
        }
        Ok(())
    }
}

/// Finishes each pending replay's writers, checks its stored arrays and commits the
/// replay (episode, record with its flags, preview) from staging; returns their outcomes.
#[allow(clippy::too_many_arguments)]
fn commit_replays(
    job: &UnitJob,
    inputs: &UnitInputs<'_>,
    pending: Vec<Pending>,
    (rendered, renderer): (&Physics, &str),
    expected: &PhysicsSummary,
    cameras: &[String],
    times: &mut StageTimes,
    frames_done: &mut dyn FnMut(u64) -> Result<(), AugmentError>,
) -> Result<Vec<Outcome>, AugmentError> {
    let UnitInputs {
        src, config, out, ..
    } = *inputs;
    let id = &src.episode.id;
    let mut outcomes = Vec::new();
    for p in pending {
        for w in p.writers {
            w.finish().map_err(video_err(id))?;
        }
        for d in p.depth {
            d.finish()?;
        }
        let name = replay_name(id, p.index);
        let mut ep = replay_episode(src, &name, rendered, cameras, config.depth)?;
        p.defects.episode(&mut ep);
        let mut record = record_of(job, p.index, p.sample, p.dynamics, expected);
        renderer.clone_into(&mut record.renderer);
        record.flags = timed(&mut times.checks, || p.checks.finish(&ep, &src.spec));
        record.videos = cameras
            .iter()
            .map(|c| format!("{}/{c}.mp4", raw::VIDEOS))
            .collect();
        if config.depth {
            record.depth = cameras
                .iter()
                .map(|c| format!("{}/{c}_depth.npz", raw::VIDEOS))
                .collect();
        }
        commit_replay(
            out,
            &p.staging,
            &ep,
            &src.spec,
            &record,
            p.preview.as_ref(),
            &mut || frames_done(0),
        )?;
        outcomes.push(Outcome::Kept(record));
    }
    Ok(outcomes)
}

/// A replay's record (no videos yet).
fn record_of(
    job: &UnitJob,
    index: usize,
    sample: VisualSample,
    dynamics: Option<Vec<DynamicsValue>>,
    physics: &PhysicsSummary,
) -> ReplayRecord {
    ReplayRecord {
        name: replay_name(&job.episode, index),
        task: job.task.clone(),
        episode: job.episode.clone(),
        replay: index,
        sample,
        success: physics.first_success.is_some(),
        first_success: physics.first_success,
        steps: physics.frames,
        recorded_steps: physics.recorded,
        extended: physics.extended(),
        max_state_deviation: physics.deviation,
        deviation_at: physics.deviation_at,
        subtasks: physics.subtasks.clone(),
        flags: Vec::new(),
        videos: Vec::new(),
        depth: Vec::new(),
        dynamics,
        source_hash: job.source_hash.clone(),
        renderer: String::new(),
        made_on: Some(crate::provenance::this_machine().clone()),
    }
}
