//! What the policy receives, as the reference client's `DexJoCoOpenPIEnv` builds it:
//! each mapped camera's image resized with padding to 224x224 `uint8` (openpi's
//! `image_tools.resize_with_pad`: PIL's bilinear filter, aspect kept, zeros around), the
//! proprioceptive state (the first 23 values of the DexJoCo state for one arm, 46 for two,
//! `float64`; one arm padded to 46 with `--pad-state-dim46`) and the prompt, in that
//! order.

use fast_image_resize::images::Image;
use fast_image_resize::{FilterType, PixelType, ResizeAlg, ResizeOptions, Resizer};
use rmpv::Value;

use crate::config::POLICY_IMAGE;
use crate::wire::NdArray;

/// An RGB image, rows top-down, 3 bytes per pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Rgb {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Pixels.
    pub data: Vec<u8>,
}

/// openpi's `resize_with_pad(image, 224, 224)`: scaled by `max(w / 224, h / 224)` to
/// `int(w / ratio) x int(h / ratio)` with PIL's bilinear filter (a triangle filter widened
/// by the scale when shrinking), pasted at `(int((224 - w') / 2), int((224 - h') / 2))`
/// on black. An image already 224x224 is returned as it is.
pub fn resize_with_pad(img: &Rgb, side: u32) -> Rgb {
    if img.width == side && img.height == side {
        return img.clone();
    }
    let (w, h) = (f64::from(img.width), f64::from(img.height));
    let ratio = (w / f64::from(side)).max(h / f64::from(side));
    let (rw, rh) = ((w / ratio) as u32, (h / ratio) as u32);
    let resized = resize(img, rw.max(1), rh.max(1));
    let mut out = vec![0u8; (side * side * 3) as usize];
    let pad_h = side.saturating_sub(resized.height) / 2;
    let pad_w = side.saturating_sub(resized.width) / 2;
    for y in 0..resized.height.min(side) {
        let src = (y * resized.width * 3) as usize;
        let dst = (((y + pad_h) * side + pad_w) * 3) as usize;
        let n = (resized.width.min(side) * 3) as usize;
        out[dst..dst + n].copy_from_slice(&resized.data[src..src + n]);
    }
    Rgb {
        width: side,
        height: side,
        data: out,
    }
}

/// A bilinear (PIL's convolution) resize.
fn resize(img: &Rgb, width: u32, height: u32) -> Rgb {
    let src = Image::from_vec_u8(img.width, img.height, img.data.clone(), PixelType::U8x3)
        .expect("an RGB buffer of its size");
    let mut dst = Image::new(width, height, PixelType::U8x3);
    let options = ResizeOptions::new().resize_alg(ResizeAlg::Convolution(FilterType::Bilinear));
    Resizer::new()
        .resize(&src, &mut dst, &options)
        .expect("same pixel type");
    Rgb {
        width,
        height,
        data: dst.into_vec(),
    }
}

/// The observation key of the environment state (`--environment-state`).
pub const ENVIRONMENT_STATE_KEY: &str = "environment_state";

/// The parts of one observation.
pub struct Observation<'a> {
    /// `(policy key, image)` in the config's order.
    pub images: Vec<(&'a str, Rgb)>,
    /// The proprioceptive state.
    pub state: Vec<f64>,
    /// The environment state (`--environment-state`): the objects now, then dh.
    pub environment_state: Option<Vec<f64>>,
    /// The prompt.
    pub prompt: &'a str,
    /// `dexjoco/...` keys for oracle and privileged policies (`--privileged-keys`).
    pub privileged: Option<Privileged<'a>>,
}

/// What only an oracle should read.
pub struct Privileged<'a> {
    /// The episode's full DexJoCo state at its start (after the restore).
    pub initial_state: &'a [f64],
    /// The episode's index in the run.
    pub episode: usize,
    /// The control step the observation is of.
    pub step: usize,
}

impl Observation<'_> {
    /// The MessagePack map the reference client sends: images (224x224x3 `uint8`),
    /// `state` (`float64`), `prompt`; then the privileged keys when asked.
    pub fn to_value(&self) -> Value {
        let mut map: Vec<(Value, Value)> = self
            .images
            .iter()
            .map(|(k, img)| {
                let a = NdArray::u8(
                    vec![img.height as usize, img.width as usize, 3],
                    img.data.clone(),
                );
                (Value::from(*k), a.to_value())
            })
            .collect();
        map.push((
            Value::from("state"),
            NdArray::f64(vec![self.state.len()], &self.state).to_value(),
        ));
        if let Some(e) = &self.environment_state {
            map.push((
                Value::from(ENVIRONMENT_STATE_KEY),
                NdArray::f64(vec![e.len()], e).to_value(),
            ));
        }
        map.push((Value::from("prompt"), Value::from(self.prompt)));
        if let Some(p) = &self.privileged {
            map.push((
                Value::from("dexjoco/initial_state"),
                NdArray::f64(vec![p.initial_state.len()], p.initial_state).to_value(),
            ));
            map.push((
                Value::from("dexjoco/episode"),
                Value::from(p.episode as u64),
            ));
            map.push((Value::from("dexjoco/step"), Value::from(p.step as u64)));
        }
        Value::Map(map)
    }
}

/// The proprioceptive state a policy receives: the first `width` values of the DexJoCo
/// state, zero-padded to 46 when `pad46`.
pub fn policy_state(state: &[f64], width: usize, pad46: bool) -> Vec<f64> {
    let mut s = state[..width].to_vec();
    if pad46 && s.len() < 46 {
        s.resize(46, 0.0);
    }
    s
}

/// The side of the policy's images.
pub const SIDE: u32 = POLICY_IMAGE;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resize_with_pad_keeps_the_aspect_and_centres_on_black() {
        // 448 x 224 (w x h): halved to 224 x 112, pasted 56 rows down.
        let img = Rgb {
            width: 448,
            height: 224,
            data: vec![200; 448 * 224 * 3],
        };
        let out = resize_with_pad(&img, 224);
        assert_eq!((out.width, out.height), (224, 224));
        let px = |x: u32, y: u32| out.data[((y * 224 + x) * 3) as usize];
        assert_eq!(px(100, 55), 0);
        assert_eq!(px(100, 56), 200);
        assert_eq!(px(100, 167), 200);
        assert_eq!(px(100, 168), 0);
        let same = Rgb {
            width: 224,
            height: 224,
            data: (0..224 * 224 * 3).map(|i| (i % 251) as u8).collect(),
        };
        assert_eq!(resize_with_pad(&same, 224), same);
    }
}
