//! Rendering a unit with the Warp batch renderer (`--renderer warp`): the episode is
//! simulated here as with OpenGL; each step's geom poses go into batches (one per camera
//! of the replays: worlds = frames x replays), which the worker renders many at a time;
//! the frames then go, in step order, through the same checks and encoders.

use std::cell::RefCell;
use std::time::Instant;

use dexjoco_sim::Scene;
use dexjoco_sim::randomize::warp_world;
use dexjoco_sim::warp::{WarpBatch, WarpRenderer, WarpTimes, WarpWorker, view_fovy, view_slots};

use crate::assets::TaskAssets;
use crate::config::AugmentConfig;
use crate::error::{AugmentError, sim_err};
use crate::physics::{Physics, new_env, replay};
use crate::profile::{StageTimes, timed};
use crate::render::{Pending, UnitInputs, unit_render_settings};

thread_local! {
    /// One Warp renderer (worker process and scene) per worker thread, as for OpenGL.
    static WARP: RefCell<Option<(String, WarpRenderer)>> = const { RefCell::new(None) };
}

/// What decides whether an open renderer serves a unit: the scene and the settings.
fn key(assets: &TaskAssets, config: &AugmentConfig) -> String {
    format!(
        "{} {:?} {:?} {:?}",
        assets.key,
        unit_render_settings(config),
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
    let settings = unit_render_settings(config);
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
        opened(&warp.info().describe());
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

/// Replays the episode on `scene`, rendering every pending replay's views of each step
/// with this thread's Warp renderer in batches; returns the simulation and the renderer's
/// name.
pub(crate) fn draw_replays(
    inputs: &UnitInputs<'_>,
    scene: &Scene,
    fixed: &[usize],
    pending: &mut [Pending],
    times: &mut StageTimes,
    frames_done: &mut dyn FnMut(u64) -> Result<(), AugmentError>,
) -> Result<(Physics, String), AugmentError> {
    let UnitInputs {
        src,
        assets,
        config,
        ..
    } = *inputs;
    let id = &src.episode.id;
    let model = &assets.scene.model;
    let mut env = new_env(src, scene, &src.spec)?;
    with_warp(assets, config, |warp| {
        warp.take_times();
        let views: Vec<Vec<_>> = pending
            .iter()
            .map(|p| p.sample.views(fixed).collect())
            .collect();
        let cameras = views.first().map_or(0, Vec::len);
        let mut slots = Vec::with_capacity(cameras);
        for v in views.first().into_iter().flatten() {
            slots.push(warp.slot_of(view_fovy(model, *v)).map_err(sim_err(id))?);
        }
        // Frames per flush: as many as fill a batch of frames x replays worlds.
        let per_batch = (warp.worlds() / pending.len().max(1)).max(1);
        let mut batches = Batches {
            cameras: slots.iter().map(|&s| WarpBatch::new(s)).collect(),
            first_step: 0,
        };
        let started = Instant::now();
        let mut drawing = 0.0;
        let physics = replay(src, &mut env, config, |env, k| {
            let step_started = Instant::now();
            let data = env.data();
            timed(&mut times.scene, || {
                for (c, batch) in batches.cameras.iter_mut().enumerate() {
                    let f = batch.push_frame(data);
                    for (p, v) in pending.iter().zip(&views) {
                        batch
                            .push_world(f, warp_world(model, data, v[c], &p.sample, &assets.table));
                    }
                }
            });
            let mut r = Ok(());
            if batches
                .cameras
                .first()
                .is_some_and(|b| b.frames() == per_batch)
            {
                r = flush(warp, &mut batches, pending, id, times, frames_done);
                batches.first_step = k + 1;
            }
            drawing += step_started.elapsed().as_secs_f64();
            r
        });
        let flush_started = Instant::now();
        let last = flush(warp, &mut batches, pending, id, times, frames_done);
        drawing += flush_started.elapsed().as_secs_f64();
        times.physics += started.elapsed().as_secs_f64() - drawing;
        add_warp_times(times, &warp.take_times());
        let physics = physics?;
        last?;
        Ok((physics, warp.info().describe()))
    })
}

/// Renders the batches and hands their frames to the replays in step order (step, replay,
/// camera: as the OpenGL path does); empties them.
fn flush(
    warp: &mut WarpRenderer,
    batches: &mut Batches,
    pending: &mut [Pending],
    id: &str,
    times: &mut StageTimes,
    frames_done: &mut dyn FnMut(u64) -> Result<(), AugmentError>,
) -> Result<(), AugmentError> {
    let frames = batches.cameras.first().map_or(0, WarpBatch::frames);
    if frames == 0 {
        return Ok(());
    }
    let mut images = Vec::with_capacity(batches.cameras.len());
    for batch in &mut batches.cameras {
        images.push(warp.render(batch).map_err(sim_err(id))?.into_iter());
        batch.clear();
    }
    for j in 0..frames {
        let k = batches.first_step + j;
        for p in pending.iter_mut() {
            for (c, camera) in images.iter_mut().enumerate() {
                let frame = camera.next().expect("one image per world");
                p.take(id, c, k, frame, times)?;
            }
        }
        frames_done((pending.len() * images.len()) as u64)?;
    }
    Ok(())
}

/// The Warp renderer's times as augment's stages: building and sending the batches is the
/// scene update, ray tracing the render, copying and unpacking images the read-back.
fn add_warp_times(times: &mut StageTimes, w: &WarpTimes) {
    times.frames += w.frames;
    times.scene += w.send + w.upload;
    times.render += w.render;
    times.readback += w.readback + w.receive;
}
