//! What the light geometry changes in the image: a replay's views rendered with the full
//! and the light meshes side by side, compared frame by frame (PSNR and SSIM of the RGB
//! images as rendered, before encoding), with the triangle counts of both. `bench augment
//! --geometry full,light` prints it beside the speed-up, so users choose with numbers.

use std::sync::Arc;

use dexjoco_sim::{Frame, Geometry, RenderSettings, Renderer};
use serde::Serialize;

use crate::config::AugmentConfig;
use crate::dry_run::Trajectory;
use crate::error::{AugmentError, sim_err};
use dexjoco_sim::randomize::apply_visuals;

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

/// Peak signal-to-noise ratio of two 8-bit images, dB (infinite when identical).
pub fn psnr(a: &[u8], b: &[u8]) -> f64 {
    let mse = a
        .iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).powi(2))
        .sum::<f64>()
        / a.len().max(1) as f64;
    10.0 * (255.0 * 255.0 / mse).log10()
}

/// Structural similarity (Wang et al. 2004) of two frames' luma: 11x11 Gaussian window
/// (sigma 1.5), K1 = 0.01, K2 = 0.03, averaged over the windows inside the image.
pub fn ssim(a: &Frame, b: &Frame) -> f64 {
    let (w, h) = (a.width as usize, a.height as usize);
    let luma = |f: &Frame| -> Vec<f64> {
        f.rgb
            .chunks_exact(3)
            .map(|p| 0.299 * f64::from(p[0]) + 0.587 * f64::from(p[1]) + 0.114 * f64::from(p[2]))
            .collect()
    };
    let (x, y) = (luma(a), luma(b));
    let product = |p: &[f64], q: &[f64]| p.iter().zip(q).map(|(u, v)| u * v).collect::<Vec<_>>();
    let blur = |img: &[f64]| gaussian_valid(img, w, h);
    let (mx, my) = (blur(&x), blur(&y));
    let (sxx, syy, sxy) = (
        blur(&product(&x, &x)),
        blur(&product(&y, &y)),
        blur(&product(&x, &y)),
    );
    let (c1, c2) = ((0.01f64 * 255.0).powi(2), (0.03f64 * 255.0).powi(2));
    let n = mx.len().max(1);
    (0..mx.len())
        .map(|i| {
            let (ux, uy) = (mx[i], my[i]);
            let (vx, vy, cxy) = (sxx[i] - ux * ux, syy[i] - uy * uy, sxy[i] - ux * uy);
            ((2.0 * ux * uy + c1) * (2.0 * cxy + c2)) / ((ux * ux + uy * uy + c1) * (vx + vy + c2))
        })
        .sum::<f64>()
        / n as f64
}

/// An 11x11 Gaussian (sigma 1.5) weighted mean around every pixel whose window lies inside
/// the image (separable; rows then columns).
fn gaussian_valid(img: &[f64], w: usize, h: usize) -> Vec<f64> {
    const R: usize = 5;
    let kernel: Vec<f64> = {
        let k: Vec<f64> = (0..=2 * R)
            .map(|i| (-((i as f64 - R as f64).powi(2)) / (2.0 * 1.5 * 1.5)).exp())
            .collect();
        let s: f64 = k.iter().sum();
        k.into_iter().map(|v| v / s).collect()
    };
    if w <= 2 * R || h <= 2 * R {
        return Vec::new();
    }
    let (ow, oh) = (w - 2 * R, h - 2 * R);
    let rows: Vec<f64> = (0..h)
        .flat_map(|y| {
            let kernel = &kernel;
            (0..ow).map(move |x| (0..=2 * R).map(|i| kernel[i] * img[y * w + x + i]).sum())
        })
        .collect();
    (0..oh)
        .flat_map(|y| {
            let (kernel, rows) = (&kernel, &rows);
            (0..ow).map(move |x| {
                (0..=2 * R)
                    .map(|i| kernel[i] * rows[(y + i) * ow + x])
                    .sum()
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(w: u32, h: u32, f: impl Fn(u32, u32) -> u8) -> Frame {
        let mut rgb = Vec::new();
        for y in 0..h {
            for x in 0..w {
                rgb.extend([f(x, y); 3]);
            }
        }
        Frame {
            width: w,
            height: h,
            rgb,
            depth: None,
        }
    }

    #[test]
    fn identical_images_are_perfectly_similar() {
        let a = frame(32, 24, |x, y| ((x * 7 + y * 3) % 256) as u8);
        assert_eq!(psnr(&a.rgb, &a.rgb), f64::INFINITY);
        assert!((ssim(&a, &a) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn a_uniform_error_of_one_level_gives_48_db() {
        let a = frame(16, 16, |_, _| 100);
        let b = frame(16, 16, |_, _| 101);
        // 10 log10(255^2 / 1) = 48.13 dB.
        assert!((psnr(&a.rgb, &b.rgb) - 48.13).abs() < 0.01);
    }

    #[test]
    fn structure_lost_lowers_ssim_more_than_a_brightness_shift() {
        let a = frame(
            48,
            48,
            |x, y| if (x / 4 + y / 4) % 2 == 0 { 40 } else { 200 },
        );
        let shifted = frame(
            48,
            48,
            |x, y| if (x / 4 + y / 4) % 2 == 0 { 50 } else { 210 },
        );
        let flat = frame(48, 48, |_, _| 120);
        let (s_shift, s_flat) = (ssim(&a, &shifted), ssim(&a, &flat));
        assert!(s_shift > 0.95, "{s_shift}");
        assert!(s_flat < 0.2, "{s_flat}");
    }
}
