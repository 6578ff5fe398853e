//! `augment --dry-run`: what a run would do, before the spend. Episodes, replays and
//! frames per task, what is already on disk, and an estimate of the time from a short
//! calibration: each task's scene rendered and encoded at the chosen size and preset
//! while its first episode's actions are stepped, as augment does.

use std::collections::{BTreeMap, BTreeSet};
use std::time::Instant;

use dexjoco_core::{Episode, TaskSet};
use dexjoco_render::{CameraView, RenderSettings, Renderer};
use dexjoco_sim::mujoco_rs::prelude::MjtState;
use dexjoco_video::{VideoSpec, VideoWriter};
use serde::Serialize;

use crate::assets::load_assets;
use crate::config::{AugmentConfig, replay_name};
use crate::error::{AugmentError, sim_err, video_err};
use crate::fingerprint::OutputSettings;
use crate::inputs::{Source, read_sources};
use crate::physics::{action_row, new_env, recorded_frames, replay};
use crate::plan::{existing_replays, owned_replays};
use crate::profile::{EncoderClock, StageTimes, timed};
use dexjoco_render::randomize::{VisualSample, apply_visuals};

/// One task's share of a planned run.
#[derive(Debug, Clone, Serialize)]
pub struct PlannedTask {
    /// Task id.
    pub task: String,
    /// Episodes.
    pub episodes: usize,
    /// Replays this run owns (all, or its shard's).
    pub replays: usize,
    /// Of those, already on disk.
    pub done: usize,
    /// Frames still to render (every camera, recorded frames; an extension adds at most
    /// `--extend-steps` per replay).
    pub frames_to_render: u64,
    /// Calibrated frames/s of one worker on this task's scene (render + encode + physics),
    /// when calibrated.
    pub frames_per_s: Option<f64>,
    /// Where the calibration frames' time went, when calibrated.
    pub times: Option<StageTimes>,
}

/// A planned run and its estimate.
#[derive(Debug, Clone, Serialize)]
pub struct DryRun {
    /// Per task.
    pub tasks: Vec<PlannedTask>,
    /// Inputs that could not be replayed, with the reason.
    pub skipped: Vec<(String, String)>,
    /// Cameras rendered per replay.
    pub cameras: usize,
    /// Estimated seconds for one worker process on this machine.
    pub seconds_one_worker: Option<f64>,
    /// How the output folder's settings differ from this run's (the run would be refused
    /// without `--overwrite`).
    pub settings_differ: Vec<String>,
}

impl DryRun {
    /// Frames still to render.
    pub fn frames_to_render(&self) -> u64 {
        self.tasks.iter().map(|t| t.frames_to_render).sum()
    }

    /// The calibration's stages over every task, when calibrated.
    pub fn times(&self) -> Option<StageTimes> {
        let mut all = StageTimes::default();
        for t in self.tasks.iter().filter_map(|t| t.times.as_ref()) {
            all.add(t);
        }
        (all.frames > 0).then_some(all)
    }
}

/// Plans `config` without rendering anything but the calibration frames (`calibration`
/// frames per task; 0 skips it).
pub fn dry_run(config: &AugmentConfig, calibration: usize) -> Result<DryRun, AugmentError> {
    let tasks = TaskSet::with_dir(config.tasks_dir.as_deref())
        .map_err(|e| AugmentError::Input(format!("task specs: {e}")))?;
    let (sources, skipped) = read_sources(&config.inputs, &config.out, &tasks)?;
    let cameras = 1 + config.cameras.len();
    let owned = owned_replays(&sources, config, cameras);
    let task_ids: BTreeSet<&str> = sources.iter().map(|s| s.spec.id.as_str()).collect();
    let on_disk = existing_replays(&config.out, &task_ids);
    let mut per_task: BTreeMap<String, PlannedTask> = BTreeMap::new();
    let mut first_of_task: BTreeMap<String, usize> = BTreeMap::new();
    for (i, s) in sources.iter().enumerate() {
        let t = per_task
            .entry(s.spec.id.clone())
            .or_insert_with(|| PlannedTask {
                task: s.spec.id.clone(),
                episodes: 0,
                replays: 0,
                done: 0,
                frames_to_render: 0,
                frames_per_s: None,
                times: None,
            });
        first_of_task.entry(s.spec.id.clone()).or_insert(i);
        t.episodes += 1;
        let disk = on_disk.get(&(s.spec.id.clone(), s.episode.id.clone()));
        let frames = (recorded_frames(s, config) * cameras) as u64;
        for &r in &owned[i] {
            t.replays += 1;
            let done = disk.is_some_and(|d| {
                d.get(&r)
                    .is_some_and(|rec| rec.name == replay_name(&s.episode.id, r))
            });
            if done {
                t.done += 1;
            } else {
                t.frames_to_render += frames;
            }
        }
    }
    let mut settings_differ = Vec::new();
    if let Ok(bytes) = fs_err::read(config.out.join(crate::config::SETTINGS_FILE)) {
        let mut inputs = Vec::new();
        let mut pools = BTreeMap::new();
        for task in first_of_task.keys() {
            let spec = &sources[first_of_task[task]].spec;
            pools.insert(task.clone(), load_assets(config, spec)?.pool);
            inputs.push((
                task.clone(),
                crate::fingerprint::scene_hash(&config.scene, spec)?,
                OutputSettings::spec_hash(spec),
            ));
        }
        let now = OutputSettings::of(
            config,
            inputs
                .into_iter()
                .map(|(t, sc, sp)| (t.clone(), sc, &pools[&t], sp)),
        );
        match serde_json::from_slice::<OutputSettings>(&bytes) {
            Ok(was) => settings_differ = now.differences(&was),
            Err(e) => settings_differ.push(format!("unreadable settings file ({e})")),
        }
    }
    // The calibration draws with OpenGL one frame at a time; the Warp renderer's speed
    // is a batch's (`bench augment --renderer warp` measures it).
    let calibration = if config.renderer == dexjoco_render::RendererKind::Warp && calibration > 0 {
        tracing::warn!(
            "no time estimate with --renderer warp: measure it with `bench augment --renderer warp`"
        );
        0
    } else {
        calibration
    };
    if calibration > 0 {
        for (task, t) in per_task.iter_mut() {
            if t.frames_to_render == 0 {
                continue;
            }
            let s = &sources[first_of_task[task]];
            let (fps, times) = calibrate(s, config, calibration)?;
            t.frames_per_s = Some(fps);
            t.times = Some(times);
        }
    }
    let seconds_one_worker = (calibration > 0).then(|| {
        per_task
            .values()
            .filter_map(|t| t.frames_per_s.map(|f| t.frames_to_render as f64 / f))
            .sum()
    });
    Ok(DryRun {
        tasks: per_task.into_values().collect(),
        skipped: skipped.into_iter().map(|k| (k.source, k.reason)).collect(),
        cameras,
        seconds_one_worker,
        settings_differ,
    })
}

/// Frames/s of one worker on `src`'s task, and where its time went: `frames` steps of its
/// actions, every camera rendered with the first sampled look and encoded, after three
/// warm-up steps.
fn calibrate(
    src: &crate::inputs::Source,
    config: &AugmentConfig,
    frames: usize,
) -> Result<(f64, StageTimes), AugmentError> {
    let id = &src.episode.id;
    let assets = load_assets(config, &src.spec)?;
    let fixed = assets.fixed_cameras(&config.cameras, id)?;
    let sample = assets.sample(config.seed, &src.key(), 0);
    let mut renderer = Renderer::new(
        &assets.scene.model,
        RenderSettings {
            depth: config.depth,
            ..config.settings
        },
    )
    .map_err(sim_err(id))?;
    let tmp = tempfile::tempdir().map_err(|e| AugmentError::Input(e.to_string()))?;
    let spec = VideoSpec {
        width: config.settings.width,
        height: config.settings.height,
        fps: 30,
        codec: config.video.codec(),
    };
    let keyframes = config.video.keyframes(Vec::new());
    let mut writers: Vec<VideoWriter> = (0..=fixed.len())
        .map(|c| VideoWriter::create_with(tmp.path().join(format!("{c}.mp4")), spec, &keyframes))
        .collect::<Result<_, _>>()
        .map_err(video_err(id))?;
    let mut env = new_env(src, &assets.scene, &src.spec)?;
    let actions = src.episode.array(Episode::ACTION).expect("checked");
    let warmup = 3;
    let mut started = Instant::now();
    let mut rendered = 0usize;
    let mut times = StageTimes::default();
    for k in 0..warmup + frames {
        if k == warmup {
            started = Instant::now();
            rendered = 0;
            times = StageTimes::default();
            renderer.take_times();
        }
        let views = std::iter::once(sample.camera.view())
            .chain(fixed.iter().map(|i| CameraView::Fixed(*i)));
        for (view, w) in views.zip(writers.iter_mut()) {
            renderer.update_scene(env.data_mut(), view);
            timed(&mut times.scene, || {
                apply_visuals(&mut renderer, &sample, &assets.table)
            });
            let frame = renderer.draw().map_err(sim_err(id))?;
            timed(&mut times.encode_feed, || w.write_frame(&frame.rgb)).map_err(video_err(id))?;
            rendered += 1;
        }
        timed(&mut times.physics, || env.step(action_row(actions, k))).map_err(sim_err(id))?;
    }
    let fps = rendered as f64 / started.elapsed().as_secs_f64().max(1e-9);
    times.add_render(&renderer.take_times());
    // The encoders' CPU time, warm-up frames included (a few per cent of it).
    let encoders = EncoderClock::start();
    for w in writers {
        w.finish().map_err(video_err(id))?;
    }
    times.encode_cpu = encoders.seconds() * frames as f64 / (frames + warmup) as f64;
    Ok((fps, times))
}

/// The render-only cost of `config`'s first episode: its scene drawn in the states of its
/// simulated trajectory (simulated once before timing; each drawn state set and forwarded)
/// from the views a replay renders (the sampled third-person view and the fixed cameras,
/// with the sampled looks), with no stepping and no encoding. After loading, simulating and
/// a warm-up, `ready` is called (a benchmark starts several processes together there);
/// then `frames` frames are timed, spread evenly over the trajectory. Returns frames/s.
pub fn render_only(
    config: &AugmentConfig,
    frames: usize,
    ready: &mut dyn FnMut(),
) -> Result<f64, AugmentError> {
    let mut t = Trajectory::of_first_episode(config)?;
    let id = t.src.episode.id.clone();
    let fixed = t.assets.fixed_cameras(&config.cameras, &id)?;
    let mut renderer =
        Renderer::new(&t.assets.scene.model, config.settings).map_err(sim_err(&id))?;
    let samples: Vec<VisualSample> = (0..config.replays.max(1))
        .map(|r| t.assets.sample(config.seed, &t.src.key(), r))
        .collect();
    // Draw calls (each draws every view) over which the trajectory is spread.
    let span = frames.div_ceil(1 + fixed.len()).max(1);
    let mut draw = |k: usize| -> Result<usize, AugmentError> {
        let sample = &samples[k % samples.len()];
        t.go_to((k % span) * t.states.len() / span)?;
        let views = std::iter::once(sample.camera.view())
            .chain(fixed.iter().map(|i| CameraView::Fixed(*i)));
        let mut n = 0;
        for view in views {
            renderer.update_scene(t.env.data_mut(), view);
            apply_visuals(&mut renderer, sample, &t.assets.table);
            renderer.draw().map_err(sim_err(&id))?;
            n += 1;
        }
        Ok(n)
    };
    for k in 0..3 {
        draw(k)?;
    }
    ready();
    let started = Instant::now();
    let mut rendered = 0;
    let mut k = 0;
    while rendered < frames {
        rendered += draw(k)?;
        k += 1;
    }
    Ok(rendered as f64 / started.elapsed().as_secs_f64().max(1e-9))
}

/// `config`'s first episode, its task's scene, and its simulated trajectory (the full
/// physics state before every step), for drawing the episode's states without stepping
/// (the render-only limit, the light-geometry comparison).
pub(crate) struct Trajectory {
    pub(crate) src: Source,
    pub(crate) assets: crate::assets::TaskAssets,
    pub(crate) env: dexjoco_sim::TaskEnv,
    pub(crate) states: Vec<Box<[f64]>>,
}

impl Trajectory {
    /// Reads the inputs, loads the first episode's scene and simulates it once.
    pub(crate) fn of_first_episode(config: &AugmentConfig) -> Result<Self, AugmentError> {
        let tasks = TaskSet::with_dir(config.tasks_dir.as_deref())
            .map_err(|e| AugmentError::Input(format!("task specs: {e}")))?;
        let (sources, _) = read_sources(&config.inputs, &config.out, &tasks)?;
        let src = sources
            .into_iter()
            .next()
            .ok_or_else(|| AugmentError::Input("no episode to render".into()))?;
        let assets = load_assets(config, &src.spec)?;
        let mut env = new_env(&src, &assets.scene, &src.spec)?;
        let mut states = Vec::new();
        replay(&src, &mut env, config, |env, _| {
            states.push(env.data().state(FULL_STATE));
            Ok(())
        })?;
        Ok(Self {
            src,
            assets,
            env,
            states,
        })
    }

    /// Sets the simulation to state `k` (and its derived quantities) for drawing.
    pub(crate) fn go_to(&mut self, k: usize) -> Result<(), AugmentError> {
        let data = self.env.data_mut();
        data.set_state(&self.states[k], FULL_STATE)
            .map_err(|e| AugmentError::Input(format!("episode '{}': {e}", self.src.episode.id)))?;
        data.forward();
        Ok(())
    }
}

/// The state a trajectory records: everything physics needs to resume.
const FULL_STATE: u32 = MjtState::mjSTATE_FULLPHYSICS as u32;
