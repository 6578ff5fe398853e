//! Rendering a unit with the Warp batch renderer (`--renderer warp`): the episode is
//! simulated here as with OpenGL; each step's geom poses go into batches (one per camera
//! of the replays: worlds = frames x replays), which the worker renders many at a time;
//! the frames then go, in step order, through the same checks and encoders.

use std::cell::RefCell;
use std::time::Instant;

use dexjoco_render::Frame;
use dexjoco_render::randomize::VisualSample;
use dexjoco_render::randomize::warp_world;
use dexjoco_render::warp::{WarpBatch, WarpRenderer, WarpTimes, WarpWorker, view_fovy, view_slots};
use dexjoco_sim::Scene;

use crate::assets::TaskAssets;
use crate::config::AugmentConfig;
use crate::error::{AugmentError, sim_err};
use crate::physics::{Physics, new_env, replay};
use crate::profile::{StageTimes, timed};

thread_local! {
    /// One Warp renderer (worker process and scene) per worker thread, as for OpenGL.
    static WARP: RefCell<Option<(String, WarpRenderer)>> = const { RefCell::new(None) };
}

/// What decides whether an open renderer serves a unit: the scene and the settings.
fn key(assets: &TaskAssets, config: &AugmentConfig) -> String {
    format!(
        "{} {:?} {:?} {:?}",
        assets.key,
        config.unit_render_settings(),
        config.cameras,
        config.warp
    )
}

fn with_warp<T>(
    assets: &TaskAssets,
    config: &AugmentConfig,
    f: impl FnOnce(&mut WarpRenderer) -> Result<T, AugmentError>,
) -> Result<T, AugmentError> {
    let key = key(assets, config);
    WARP.with(|cell| {
        let mut slot = cell.borrow_mut();
        if !matches!(&*slot, Some((k, _)) if *k == key) {
            *slot = None;
            let r = open(assets, config)?;
            *slot = Some((key, r));
        }
        let (_, r) = slot.as_mut().expect("set");
        f(r)
    })
}

/// Starts a worker and opens the task's scene in it, one view slot per field of view of
/// the third-person view and the fixed cameras.
fn open(assets: &TaskAssets, config: &AugmentConfig) -> Result<WarpRenderer, AugmentError> {
    let task = &assets.key;
    let model = &assets.scene.model;
    let fixed = assets.fixed_cameras(&config.cameras, task)?;
    let sample = assets.sample(config.seed, "warm-up", 0);
    let slots = view_slots(model, sample.views(&fixed));
    let worker = WarpWorker::start(&config.warp).map_err(sim_err(task))?;
    let worlds = worker.batch_worlds();
    let settings = config.unit_render_settings();
    WarpRenderer::open(
        worker,
        &assets.xml,
        model,
        settings,
        worlds,
        assets.table.geom,
        &slots,
    )
    .map_err(sim_err(task))
}

/// Opens the renderer for `assets`' scene and renders one frame (Warp compiles its
/// kernels on first use; cached on disk after the first run), telling `opened` the device.
pub(crate) fn preload(
    assets: &TaskAssets,
    config: &AugmentConfig,
    opened: &mut dyn FnMut(&str),
) -> Result<(), AugmentError> {
    with_warp(assets, config, |warp| {
        opened(&format!(
            "{} ({})",
            dexjoco_workers::WARP_WORDS,
            warp.info().describe()
        ));
        let model = &assets.scene.model;
        let mut data = dexjoco_sim::mujoco_rs::prelude::MjData::new(model.clone());
        data.forward();
        let sample = assets.sample(config.seed, "warm-up", 0);
        let view = sample.camera.view();
        let slot = warp
            .slot_of(view_fovy(model, view))
            .map_err(sim_err(&assets.key))?;
        let mut batch = WarpBatch::new(slot);
        let f = batch.push_frame(&data);
        batch.push_world(f, warp_world(model, &data, view, &sample, &assets.table));
        warp.render(&batch).map_err(sim_err(&assets.key))?;
        warp.take_times();
        Ok(())
    })
}

/// Whether this thread's Warp renderer is open for `assets`' scene and `config`.
pub(crate) fn ready(assets: &TaskAssets, config: &AugmentConfig) -> bool {
    let key = key(assets, config);
    WARP.with(|cell| matches!(&*cell.borrow(), Some((k, _)) if *k == key))
}

/// Stops this thread's worker.
pub(crate) fn close() {
    WARP.with(|cell| cell.borrow_mut().take());
}

/// The batches of one flush: one per camera, each of frames x replays worlds.
struct Batches {
    cameras: Vec<WarpBatch>,
    /// The step of the batch's first frame.
    first_step: usize,
}

/// What a unit renders from: the episode, its task's assets, the settings, the
/// simulation's scene and the fixed cameras.
pub(crate) struct Source<'a> {
    pub(crate) src: &'a crate::inputs::Source,
    pub(crate) assets: &'a TaskAssets,
    pub(crate) config: &'a AugmentConfig,
    pub(crate) scene: &'a Scene,
    pub(crate) fixed: &'a [usize],
}

/// Takes replay `r`'s camera `c` image of step `k` (checks, encoder, preview).
pub(crate) type TakeFrame<'a> =
    dyn FnMut(usize, usize, usize, Frame, &mut StageTimes) -> Result<(), AugmentError> + 'a;

/// Replays the episode, rendering each replay's (`samples`') views of every step with this
/// thread's Warp renderer in batches and handing the images to `take` in step order;
/// returns the simulation and the renderer's name.
pub(crate) fn draw_replays(
    source: &Source<'_>,
    samples: &[VisualSample],
    times: &mut StageTimes,
    take: &mut TakeFrame<'_>,
    frames_done: &mut dyn FnMut(u64) -> Result<(), AugmentError>,
) -> Result<(Physics, String), AugmentError> {
    let Source {
        src,
        assets,
        config,
        scene,
        fixed,
    } = *source;
    let id = &src.episode.id;
    let model = &assets.scene.model;
    let mut env = new_env(src, scene, &src.spec)?;
    with_warp(assets, config, |warp| {
        warp.take_times();
        let views: Vec<Vec<_>> = samples.iter().map(|s| s.views(fixed).collect()).collect();
        let mut slots = Vec::new();
        for v in views.first().into_iter().flatten() {
            slots.push(warp.slot_of(view_fovy(model, *v)).map_err(sim_err(id))?);
        }
        // Frames per flush: as many as fill a batch of frames x replays worlds.
        let per_batch = (warp.worlds() / samples.len().max(1)).max(1);
        let mut batches = Batches {
            cameras: slots.iter().map(|&s| WarpBatch::new(s)).collect(),
            first_step: 0,
        };
        let mut flusher = Flush {
            warp,
            replays: samples.len(),
            id,
            take,
            frames_done,
        };
        let started = Instant::now();
        let mut drawing = 0.0;
        let physics = replay(src, &mut env, config, |env, k| {
            let step_started = Instant::now();
            let data = env.data();
            timed(&mut times.scene, || {
                for (c, batch) in batches.cameras.iter_mut().enumerate() {
                    let f = batch.push_frame(data);
                    for (s, v) in samples.iter().zip(&views) {
                        batch.push_world(f, warp_world(model, data, v[c], s, &assets.table));
                    }
                }
            });
            let mut r = Ok(());
            if batches
                .cameras
                .first()
                .is_some_and(|b| b.frames() == per_batch)
            {
                r = flusher.flush(&mut batches, times);
                batches.first_step = k + 1;
            }
            drawing += step_started.elapsed().as_secs_f64();
            r
        });
        let flush_started = Instant::now();
        let last = flusher.flush(&mut batches, times);
        drawing += flush_started.elapsed().as_secs_f64();
        times.physics += started.elapsed().as_secs_f64() - drawing;
        let warp = flusher.warp;
        add_warp_times(times, &warp.take_times());
        let physics = physics?;
        last?;
        Ok((physics, warp.info().describe()))
    })
}

/// Where rendered batches go.
struct Flush<'a, 'b> {
    warp: &'a mut WarpRenderer,
    replays: usize,
    id: &'a str,
    take: &'a mut TakeFrame<'b>,
    frames_done: &'a mut dyn FnMut(u64) -> Result<(), AugmentError>,
}

impl Flush<'_, '_> {
    /// Renders the batches and hands their frames over in step order (step, replay,
    /// camera: as the OpenGL path does); empties them.
    fn flush(&mut self, batches: &mut Batches, times: &mut StageTimes) -> Result<(), AugmentError> {
        let frames = batches.cameras.first().map_or(0, WarpBatch::frames);
        if frames == 0 {
            return Ok(());
        }
        let mut images = Vec::with_capacity(batches.cameras.len());
        for batch in &mut batches.cameras {
            images.push(
                self.warp
                    .render(batch)
                    .map_err(sim_err(self.id))?
                    .into_iter(),
            );
            batch.clear();
        }
        for j in 0..frames {
            let k = batches.first_step + j;
            for r in 0..self.replays {
                for (c, camera) in images.iter_mut().enumerate() {
                    let frame = camera.next().expect("one image per world");
                    (self.take)(r, c, k, frame, times)?;
                }
            }
            (self.frames_done)((self.replays * images.len()) as u64)?;
        }
        Ok(())
    }
}

/// The Warp renderer's times as augment's stages: building and sending the batches is the
/// scene update, ray tracing the render, copying and unpacking images the read-back.
fn add_warp_times(times: &mut StageTimes, w: &WarpTimes) {
    times.frames += w.frames;
    times.scene += w.send + w.upload;
    times.render += w.render;
    times.readback += w.readback + w.receive;
}
