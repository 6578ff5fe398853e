//! How alike two images are: PSNR over the RGB bytes and SSIM over luma (Wang et al.
//! 2004: 11x11 Gaussian window, sigma 1.5, constants for 8-bit data), the one image
//! comparison of the project: the Warp renderer against OpenGL (`dexjoco-dev bench
//! fidelity`) and the light geometry against the full one (`geometry_difference` in
//! augment) are measured with it.

use crate::render::Frame;

/// PSNR (dB) and SSIM of one image pair.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Fidelity {
    /// Peak signal-to-noise ratio over the RGB bytes, dB (infinite when equal).
    pub psnr: f64,
    /// Mean structural similarity of the luma, in [-1, 1] (1: equal).
    pub ssim: f64,
    /// Mean absolute difference per RGB byte.
    pub mean_abs: f64,
}

/// Compares two frames of the same size.
///
/// # Panics
/// When their sizes differ.
pub fn compare(a: &Frame, b: &Frame) -> Fidelity {
    assert_eq!(
        (a.width, a.height),
        (b.width, b.height),
        "frames of different sizes"
    );
    let abs: f64 = a
        .rgb
        .iter()
        .zip(&b.rgb)
        .map(|(&x, &y)| (f64::from(x) - f64::from(y)).abs())
        .sum();
    Fidelity {
        psnr: psnr(&a.rgb, &b.rgb),
        ssim: ssim(a, b),
        mean_abs: abs / a.rgb.len().max(1) as f64,
    }
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

/// BT.601 luma of each pixel.
fn luma(f: &Frame) -> Vec<f64> {
    f.rgb
        .chunks_exact(3)
        .map(|p| 0.299 * f64::from(p[0]) + 0.587 * f64::from(p[1]) + 0.114 * f64::from(p[2]))
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

    fn frame16(rgb: Vec<u8>) -> Frame {
        Frame {
            width: 16,
            height: 16,
            rgb,
            depth: None,
        }
    }

    #[test]
    fn equal_frames_are_perfect_and_noise_lowers_both_measures() {
        let a = frame16((0..16 * 16 * 3).map(|i| (i * 7 % 251) as u8).collect());
        let same = compare(&a, &a);
        assert!(same.psnr.is_infinite() && (same.ssim - 1.0).abs() < 1e-12);
        let b = frame16(a.rgb.iter().map(|v| v.wrapping_add(8)).collect());
        let off = compare(&a, &b);
        assert!(off.psnr < 40.0 && off.ssim < 1.0, "{off:?}");
        // A uniform shift of 8 levels (no wraparound below 248): PSNR 20 log10(255/8).
        let flat = frame16(vec![100; 16 * 16 * 3]);
        let brighter = frame16(vec![108; 16 * 16 * 3]);
        let f = compare(&flat, &brighter);
        assert!((f.psnr - 20.0 * (255.0f64 / 8.0).log10()).abs() < 1e-9);
        assert!((f.mean_abs - 8.0).abs() < 1e-12);
    }
}
