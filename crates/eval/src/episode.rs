//! One evaluated episode, as the reference client's episode loop runs it: reset (from
//! the episode's initial state), click_mouse's 30 warm-up actions, the first observation;
//! then each step merges the chunks that are due, executes the buffered action for the
//! step (or holds the pose when none is), records the cameras, and asks for a new chunk
//! when fewer than `replan_ratio x horizon` actions remain and none is on its way; until
//! the task succeeds, fails or reaches its step cap.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use dexjoco_core::{Episode, TaskSpec};
use dexjoco_render::randomize::apply_visuals;
use dexjoco_render::{CameraView, Renderer};
use dexjoco_sim::dynamics::apply_dynamics;
use dexjoco_sim::{EnvOptions, Scene, TaskEnv};
use dexjoco_video::VideoWriter;

use crate::chunks::{ActionBuffer, stay_action, to_env_action};
use crate::error::{EvalError, sim_err};
use crate::inference::Inference;
use crate::observe::{Observation, Privileged, Rgb, SIDE, policy_state, resize_with_pad};
use crate::output::EpisodeRecord;
use crate::stage::{Draws, Stage, View, episode_seed};

/// click_mouse's warm-up: 30 steps of this action (policy layout) before the first
/// observation, "to align with the dataset" (the reference client).
const CLICK_MOUSE_WARMUP: [f64; 22] = [
    -4.4294e-01,
    1.3729e-06,
    1.5170e00,
    -3.14156462e00,
    -6.91584035e-05,
    -1.40317984e-03,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.0,
    0.263,
    0.0,
    0.0,
    0.0,
];

/// The control rate the reference paces its loop to.
const HZ: f64 = 30.0;

/// What the episode's loop produced, besides its videos.
struct Rollout {
    actions: Vec<Vec<f64>>,
    states: Vec<Vec<f64>>,
    environment: Vec<Vec<f64>>,
    success_step: Option<usize>,
    steps: usize,
    ended_by: &'static str,
    chunks: usize,
    held: usize,
    pressed: Vec<Vec<u8>>,
    subtasks: Vec<dexjoco_core::SubtaskSpan>,
}

/// Runs episode `k` from `state0` into the staging folder `dir` (videos, rollout);
/// returns its record. `tick` is called after every step.
pub(crate) fn run_episode(
    stage: &mut Stage,
    k: usize,
    state0: &[f64],
    inference: &mut Inference,
    dir: &Path,
    server_metadata: &serde_json::Value,
    tick: &mut dyn FnMut(),
) -> Result<EpisodeRecord, EvalError> {
    let what = format!("{} episode {k}", stage.spec.id);
    let seed = episode_seed(stage.config.options.seed, k);
    let draws = stage.draws(seed)?;
    let scene = match &draws.dynamics {
        Some(values) => Scene {
            model: Arc::new(
                apply_dynamics(&stage.spec, &stage.scene.model, values).map_err(sim_err(&what))?,
            ),
            path: stage.scene.path.clone(),
        },
        None => stage.scene.clone(),
    };
    let env = TaskEnv::from_initial_state(&scene, &stage.spec, state0, EnvOptions::default())
        .map_err(sim_err(&what))?;
    let rendered_before = stage.frames_rendered;
    let start = env.state();
    fs_err::create_dir_all(dir).map_err(crate::error::io_err("create", dir))?;
    let mut videos = if stage.config.options.videos {
        stage
            .video_writers(dir)
            .map_err(|source| EvalError::Video {
                what: what.clone(),
                source,
            })?
    } else {
        Vec::new()
    };
    let mut looper = Loop {
        stage,
        env,
        draws: &draws,
        k,
        start: &start,
        what: &what,
        tick,
    };
    let rollout = looper.run(inference, &mut videos)?;
    for (_, w) in videos {
        w.finish().map_err(|source| EvalError::Video {
            what: what.clone(),
            source,
        })?;
    }
    write_rollout(dir, &stage.spec, &rollout, k)?;
    let seconds = inference.take_seconds();
    let opts = &stage.config.options;
    Ok(EpisodeRecord {
        episode: k,
        seed: opts.seed,
        task: stage.spec.id.clone(),
        success: rollout.success_step.is_some(),
        success_step: rollout.success_step,
        subtasks: rollout.subtasks,
        steps: rollout.steps,
        warmup_steps: stage.warmup_steps(),
        ended_by: rollout.ended_by.into(),
        step_cap: opts.step_cap,
        chunks: rollout.chunks,
        held_steps: rollout.held,
        frames_rendered: stage.frames_rendered - rendered_before,
        latency_steps: (!opts.real_time).then_some(opts.latency_steps),
        pressed_digits: rollout.pressed,
        reset: state0.to_vec(),
        initial_state: start,
        visuals: draws.visuals,
        dynamics: draws.dynamics,
        prompt: stage.config.task.prompt.clone(),
        inference_seconds: summary(&seconds),
        server_metadata: server_metadata.clone(),
    })
}

fn summary(v: &[f64]) -> [f64; 3] {
    if v.is_empty() {
        return [0.0; 3];
    }
    let min = v.iter().copied().fold(f64::MAX, f64::min);
    let max = v.iter().copied().fold(f64::MIN, f64::max);
    [min, v.iter().sum::<f64>() / v.len() as f64, max]
}

/// The loop of one episode.
struct Loop<'a> {
    stage: &'a mut Stage,
    env: TaskEnv,
    draws: &'a Draws,
    k: usize,
    start: &'a [f64],
    what: &'a str,
    tick: &'a mut dyn FnMut(),
}

impl Loop<'_> {
    fn run(
        &mut self,
        inference: &mut Inference,
        videos: &mut [(String, VideoWriter)],
    ) -> Result<Rollout, EvalError> {
        let setup = self.stage.spec.setup;
        let opts = self.stage.config.options.clone();
        let cap = self.stage.spec.step_cap;
        let mut out = Rollout {
            actions: Vec::new(),
            states: Vec::new(),
            environment: Vec::new(),
            success_step: None,
            steps: 0,
            ended_by: "step_cap",
            chunks: 0,
            held: 0,
            pressed: Vec::new(),
            subtasks: Vec::new(),
        };
        for _ in 0..self.stage.warmup_steps() {
            self.step(&CLICK_MOUSE_WARMUP, &mut out)?;
        }
        let mut buffer = ActionBuffer::new(setup);
        let mut t = 0;
        self.ask(inference, t, &mut out)?;
        self.record(videos)?;
        let started = Instant::now();
        let mut holding: Option<Vec<f64>> = None;
        loop {
            buffer.drop_expired(t);
            while let Some(chunk) = inference.due(t)? {
                buffer.merge(&chunk.actions, chunk.obs_step, t);
            }
            let action = match buffer.pop(t) {
                Some(a) => {
                    holding = None;
                    a
                }
                None => {
                    out.held += 1;
                    holding
                        .get_or_insert_with(|| {
                            stay_action(setup, &self.env.state()[..setup.proprio_dim()])
                        })
                        .clone()
                }
            };
            let verdict = self.step(&action, &mut out)?;
            let pressed = self.env.checker().keypad_presses();
            if opts.record_pressed_digits && !pressed.is_empty() {
                out.pressed.push(pressed);
            }
            t += 1;
            self.record(videos)?;
            let low = (buffer.len() as f64) < opts.replan_ratio * opts.horizon as f64;
            if low && !inference.in_flight() {
                self.ask(inference, t, &mut out)?;
            }
            if opts.real_time {
                let next = started + Duration::from_secs_f64(t as f64 / HZ);
                if let Some(wait) = next.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
            }
            let ended = if verdict.success {
                out.success_step = Some(t - 1);
                Some("success")
            } else if verdict.failure {
                Some("failure")
            } else {
                (self.env.steps() >= cap).then_some("step_cap")
            };
            if let Some(why) = ended {
                out.ended_by = why;
                out.steps = t;
                break;
            }
        }
        inference.drain()?;
        let warmup = self.stage.warmup_steps();
        out.subtasks = self
            .env
            .subtask_spans()
            .into_iter()
            .map(|mut e| {
                e.start = e.start.map(|s| s.saturating_sub(warmup));
                e.end = e.end.map(|s| s.saturating_sub(warmup));
                e
            })
            .collect();
        Ok(out)
    }

    /// One environment step with a policy-layout action, recorded.
    fn step(
        &mut self,
        policy_action: &[f64],
        out: &mut Rollout,
    ) -> Result<dexjoco_sim::Verdict, EvalError> {
        let action = to_env_action(self.stage.spec.setup, policy_action);
        out.states.push(self.env.state());
        out.environment.push(self.env.environment_state());
        let v = self.env.step(&action).map_err(sim_err(self.what))?;
        out.actions.push(action);
        (self.tick)();
        Ok(v)
    }

    /// Sends the observation of step `t`.
    fn ask(
        &mut self,
        inference: &mut Inference,
        t: usize,
        out: &mut Rollout,
    ) -> Result<(), EvalError> {
        let task = self.stage.config.task.clone();
        let setup = self.stage.spec.setup;
        let mut images = Vec::new();
        let mut rendered: Vec<(String, Rgb)> = Vec::new();
        for (policy, env_key) in &task.camera_mapping {
            let img = match rendered.iter().find(|(k, _)| k == env_key) {
                Some((_, img)) => img.clone(),
                None => {
                    let img = resize_with_pad(&self.render(env_key)?, SIDE);
                    rendered.push((env_key.clone(), img.clone()));
                    img
                }
            };
            images.push((policy.as_str(), img));
        }
        let state = self.env.state();
        let opts = &self.stage.config.options;
        let environment_state = opts.environment_state.then(|| self.env.environment_state());
        let obs = Observation {
            environment_state,
            images,
            state: policy_state(
                &state,
                setup.proprio_dim(),
                self.stage.config.options.pad_state_dim46,
            ),
            prompt: &task.prompt,
            privileged: self
                .stage
                .config
                .options
                .privileged_keys
                .then_some(Privileged {
                    initial_state: self.start,
                    episode: self.k,
                    step: t,
                }),
        };
        out.chunks += 1;
        inference.ask(obs.to_value(), t)
    }

    /// Renders the camera of an env image key in the current state.
    fn render(&mut self, env_key: &str) -> Result<Rgb, EvalError> {
        let view = match self.stage.view(env_key) {
            View::Fixed(id) => CameraView::Fixed(id),
            View::Random => self
                .draws
                .visuals
                .as_ref()
                .expect("random_camera only with --rand-full")
                .camera
                .view(),
        };
        let renderer: &mut Renderer = self
            .stage
            .renderer
            .as_mut()
            .expect("a renderer whenever a camera is mapped");
        renderer.update_scene(self.env.data_mut(), view);
        if let (Some(sample), Some(table)) = (&self.draws.visuals, &self.stage.table) {
            apply_visuals(renderer, sample, table);
        }
        let f = renderer.draw().map_err(sim_err(self.what))?;
        self.stage.frames_rendered += 1;
        Ok(Rgb {
            width: f.width,
            height: f.height,
            data: f.rgb,
        })
    }

    /// Appends the current frame of every recorded camera.
    fn record(&mut self, videos: &mut [(String, VideoWriter)]) -> Result<(), EvalError> {
        for (key, w) in videos.iter_mut() {
            let img = self.render(key)?;
            w.write_frame(&img.data)
                .map_err(|source| EvalError::Video {
                    what: self.what.to_owned(),
                    source,
                })?;
        }
        Ok(())
    }
}

/// The rollout as a DexJoCo raw episode (`replay.zarr`: the executed actions, warm-up
/// included, and the state before each).
fn write_rollout(dir: &Path, spec: &TaskSpec, r: &Rollout, k: usize) -> Result<(), EvalError> {
    let mut ep = Episode::from_rollout(format!("episode_{k:02}"), spec, &r.actions, &r.states)
        .map_err(|source| EvalError::Rollout { episode: k, source })?;
    ep.insert_rows(Episode::ENVIRONMENT_STATE, &r.environment)
        .map_err(|source| EvalError::Rollout { episode: k, source })?;
    dexjoco_formats::raw::write_replay_zarr(dir, &ep)?;
    Ok(())
}
