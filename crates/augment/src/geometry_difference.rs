//! What the light geometry changes in the image: a replay's views rendered with the full
//! and the light meshes side by side, compared frame by frame (PSNR and SSIM of the RGB
//! images as rendered, before encoding, by `dexjoco_render::compare`), with the triangle counts of both. `bench augment
//! --geometry full,light` prints it beside the speed-up, so users choose with numbers.

use std::sync::Arc;

use dexjoco_render::compare::{psnr, ssim};
use dexjoco_render::{Frame, Geometry, RenderSettings, Renderer};
use serde::Serialize;

use crate::config::AugmentConfig;
use crate::dry_run::Trajectory;
use crate::error::{AugmentError, sim_err};
use dexjoco_render::randomize::apply_visuals;

/// The light geometry against the full one on a replay's views.
#[derive(Debug, Clone, Serialize)]
pub struct GeometryDifference {
    /// Frames compared.
    pub frames: usize,
    /// Mesh triangles of the scene, full.
    pub triangles_full: usize,
    /// Mesh triangles of the scene, light.
    pub triangles_light: usize,
    /// Mean PSNR over the frames, dB (infinite for identical frames).
    pub psnr_mean: f64,
    /// Lowest PSNR of a frame, dB.
    pub psnr_min: f64,
    /// Mean SSIM (luma, 11x11 Gaussian window) over the frames.
    pub ssim_mean: f64,
    /// Lowest SSIM of a frame.
    pub ssim_min: f64,
}

/// Renders `frames` views of `config`'s first episode (replay 0's sampled view and looks,
/// spread evenly over its simulated trajectory) with the full and the light geometry and
/// compares them.
pub fn geometry_difference(
    config: &AugmentConfig,
    frames: usize,
) -> Result<GeometryDifference, AugmentError> {
    let mut t = Trajectory::of_first_episode(config)?;
    let id = t.src.episode.id.clone();
    let model = Arc::clone(&t.assets.scene.model);
    let settings = |geometry| RenderSettings {
        geometry,
        depth: false,
        ..config.settings
    };
    let mut full = Renderer::new(&model, settings(Geometry::Full)).map_err(sim_err(&id))?;
    let mut light = Renderer::new(&model, settings(Geometry::Light)).map_err(sim_err(&id))?;
    let sample = t.assets.sample(config.seed, &t.src.key(), 0);
    let n = frames.clamp(1, t.states.len());
    let mut psnrs = Vec::with_capacity(n);
    let mut ssims = Vec::with_capacity(n);
    for k in 0..n {
        t.go_to(k * t.states.len() / n)?;
        let mut draw = |r: &mut Renderer| -> Result<Frame, AugmentError> {
            r.update_scene(t.env.data_mut(), sample.camera.view());
            apply_visuals(r, &sample, &t.assets.table);
            r.draw().map_err(sim_err(&id))
        };
        let (a, b) = (draw(&mut full)?, draw(&mut light)?);
        psnrs.push(psnr(&a.rgb, &b.rgb));
        ssims.push(ssim(&a, &b));
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let min = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
    Ok(GeometryDifference {
        frames: n,
        triangles_full: full.triangles(),
        triangles_light: light.triangles(),
        psnr_mean: mean(&psnrs),
        psnr_min: min(&psnrs),
        ssim_mean: mean(&ssims),
        ssim_min: min(&ssims),
    })
}
