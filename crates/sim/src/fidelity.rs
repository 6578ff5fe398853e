//! How alike two renderings of one state are: PSNR over RGB and SSIM over luma (Wang et
//! al. 2004: 8x8 windows, stride 4, constants for 8-bit data), as the two renderers are
//! compared in docs/performance.md.

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
    let n = a.rgb.len() as f64;
    let (mut sq, mut abs) = (0.0f64, 0.0f64);
    for (&x, &y) in a.rgb.iter().zip(&b.rgb) {
        let d = f64::from(x) - f64::from(y);
        sq += d * d;
        abs += d.abs();
    }
    let mse = sq / n;
    let psnr = if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    };
    Fidelity {
        psnr,
        ssim: ssim(&luma(a), &luma(b), a.width as usize, a.height as usize),
        mean_abs: abs / n,
    }
}

/// BT.601 luma of each pixel.
fn luma(f: &Frame) -> Vec<f64> {
    f.rgb
        .chunks_exact(3)
        .map(|p| 0.299 * f64::from(p[0]) + 0.587 * f64::from(p[1]) + 0.114 * f64::from(p[2]))
        .collect()
}

/// Mean SSIM over 8x8 windows every 4 pixels.
fn ssim(a: &[f64], b: &[f64], w: usize, h: usize) -> f64 {
    const WIN: usize = 8;
    const STRIDE: usize = 4;
    let c1 = (0.01f64 * 255.0).powi(2);
    let c2 = (0.03f64 * 255.0).powi(2);
    if w < WIN || h < WIN {
        return if a == b { 1.0 } else { 0.0 };
    }
    let (mut total, mut count) = (0.0, 0usize);
    for y0 in (0..=h - WIN).step_by(STRIDE) {
        for x0 in (0..=w - WIN).step_by(STRIDE) {
            let (mut sa, mut sb, mut saa, mut sbb, mut sab) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for y in y0..y0 + WIN {
                for x in x0..x0 + WIN {
                    let (p, q) = (a[y * w + x], b[y * w + x]);
                    sa += p;
                    sb += q;
                    saa += p * p;
                    sbb += q * q;
                    sab += p * q;
                }
            }
            let m = (WIN * WIN) as f64;
            let (ma, mb) = (sa / m, sb / m);
            let va = saa / m - ma * ma;
            let vb = sbb / m - mb * mb;
            let cov = sab / m - ma * mb;
            total += ((2.0 * ma * mb + c1) * (2.0 * cov + c2))
                / ((ma * ma + mb * mb + c1) * (va + vb + c2));
            count += 1;
        }
    }
    total / count as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(rgb: Vec<u8>) -> Frame {
        Frame {
            width: 16,
            height: 16,
            rgb,
            depth: None,
        }
    }

    #[test]
    fn equal_frames_are_perfect_and_noise_lowers_both_measures() {
        let a = frame((0..16 * 16 * 3).map(|i| (i * 7 % 251) as u8).collect());
        let same = compare(&a, &a);
        assert!(same.psnr.is_infinite() && (same.ssim - 1.0).abs() < 1e-12);
        let b = frame(a.rgb.iter().map(|v| v.wrapping_add(8)).collect());
        let off = compare(&a, &b);
        assert!(off.psnr < 40.0 && off.ssim < 1.0, "{off:?}");
        // A uniform shift of 8 levels (no wraparound below 248): PSNR 20 log10(255/8).
        let flat = frame(vec![100; 16 * 16 * 3]);
        let brighter = frame(vec![108; 16 * 16 * 3]);
        let f = compare(&flat, &brighter);
        assert!((f.psnr - 20.0 * (255.0f64 / 8.0).log10()).abs() < 1e-9);
        assert!((f.mean_abs - 8.0).abs() < 1e-12);
    }
}
