//! What one Warp image is made of (camera pose, lights, headlight, table look) and
//! batches of them over frames' geom poses, packed as the worker reads them.

use mujoco_rs::prelude::{MjData, MjModel};
use mujoco_rs::wrappers::mj_model::traits::ModelType;

use crate::error::{RenderError, WarpError};
use crate::render::CameraView;

/// One world's look: view, lights, headlight and table.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldView {
    /// Camera position (world frame).
    pub cam_pos: [f64; 3],
    /// Camera orientation, row-major (columns: right, up, backwards), as `cam_xmat`.
    pub cam_mat: [f64; 9],
    /// Vertical field of view, degrees.
    pub fovy: f64,
    /// The scene's lights, in id order.
    pub lights: Vec<LightState>,
    /// Headlight ambient RGB.
    pub head_ambient: [f64; 3],
    /// Headlight diffuse RGB.
    pub head_diffuse: [f64; 3],
    /// The table-top geom's material id (-1: none, its colour then).
    pub table_matid: i32,
    /// The table-top geom's colour.
    pub table_rgba: [f32; 4],
}

/// One light as it shines in a world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightState {
    /// Position (world frame).
    pub pos: [f64; 3],
    /// Direction.
    pub dir: [f64; 3],
    /// Diffuse RGB.
    pub diffuse: [f64; 3],
}

impl WorldView {
    /// The scene as it is in `data` seen from `view`: the model's lights, headlight and
    /// table-top look (`table_geom`).
    pub fn of<M: ModelType>(
        model: &MjModel,
        data: &MjData<M>,
        view: CameraView,
        table_geom: usize,
    ) -> Self {
        let (cam_pos, cam_mat, fovy) = camera_pose(model, data, view);
        let head = &model.ffi().vis.headlight;
        let lights = (0..model.ffi().nlight as usize)
            .map(|i| LightState {
                pos: data.light_xpos()[i],
                dir: data.light_xdir()[i],
                diffuse: model.light_diffuse()[i].map(f64::from),
            })
            .collect();
        Self {
            cam_pos,
            cam_mat,
            fovy,
            lights,
            head_ambient: head.ambient.map(f64::from),
            head_diffuse: head.diffuse.map(f64::from),
            table_matid: model.geom_matid()[table_geom],
            table_rgba: model.geom_rgba()[table_geom],
        }
    }
}

/// Position, orientation and field of view of `view` as MuJoCo's renderer places it: a
/// model camera where `data` has it; the free camera as `mjv_updateCamera` computes it.
pub fn camera_pose<M: ModelType>(
    model: &MjModel,
    data: &MjData<M>,
    view: CameraView,
) -> ([f64; 3], [f64; 9], f64) {
    match view {
        CameraView::Fixed(id) => (
            data.cam_xpos()[id],
            data.cam_xmat()[id],
            model.cam_fovy()[id],
        ),
        CameraView::Orbit {
            lookat,
            distance,
            azimuth,
            elevation,
        } => {
            let (sa, ca) = azimuth.to_radians().sin_cos();
            let (se, ce) = elevation.to_radians().sin_cos();
            let fwd = [ca * ce, sa * ce, se];
            let up = [-ca * se, -sa * se, ce];
            let right = [
                fwd[1] * up[2] - fwd[2] * up[1],
                fwd[2] * up[0] - fwd[0] * up[2],
                fwd[0] * up[1] - fwd[1] * up[0],
            ];
            let pos = [0, 1, 2].map(|i| lookat[i] - distance * fwd[i]);
            let mat = [
                right[0], up[0], -fwd[0], right[1], up[1], -fwd[1], right[2], up[2], -fwd[2],
            ];
            (pos, mat, f64::from(model.ffi().vis.global.fovy))
        }
    }
}

/// Frames' geom poses and the worlds (images) to render from them, all through one view
/// slot (one field of view: see [`WarpRenderer::open`]).
#[derive(Debug, Clone, Default)]
pub struct WarpBatch {
    pub(super) slot: usize,
    frames: usize,
    geom_xpos: Vec<f32>,
    geom_xmat: Vec<f32>,
    pub(super) worlds: Vec<(usize, WorldView)>,
}

impl WarpBatch {
    /// An empty batch for view slot `slot`.
    pub fn new(slot: usize) -> Self {
        Self {
            slot,
            ..Self::default()
        }
    }

    /// Its view slot.
    pub fn slot(&self) -> usize {
        self.slot
    }

    /// Adds the geom poses of `data`'s state; returns its frame index in the batch.
    pub fn push_frame<M: ModelType>(&mut self, data: &MjData<M>) -> usize {
        self.geom_xpos
            .extend(data.geom_xpos().iter().flatten().map(|&v| v as f32));
        self.geom_xmat
            .extend(data.geom_xmat().iter().flatten().map(|&v| v as f32));
        self.frames += 1;
        self.frames - 1
    }

    /// Adds an image of frame `frame` seen as `view` says.
    pub fn push_world(&mut self, frame: usize, view: WorldView) {
        debug_assert!(frame < self.frames);
        self.worlds.push((frame, view));
    }

    /// Images in the batch.
    pub fn worlds(&self) -> usize {
        self.worlds.len()
    }

    /// Frames in the batch.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Empties the batch (its slot stays).
    pub fn clear(&mut self) {
        *self = Self::new(self.slot);
    }

    /// The request payload, in the order the worker's `unpack` reads it.
    pub(super) fn payload(&self, nlight: usize) -> Result<Vec<u8>, RenderError> {
        let mut out = Vec::with_capacity((self.geom_xpos.len() + self.geom_xmat.len()) * 4);
        let f32s = |out: &mut Vec<u8>, v: &mut dyn Iterator<Item = f32>| {
            for x in v {
                out.extend_from_slice(&x.to_le_bytes());
            }
        };
        let f = |v: f64| v as f32;
        f32s(&mut out, &mut self.geom_xpos.iter().copied());
        f32s(&mut out, &mut self.geom_xmat.iter().copied());
        for (frame, _) in &self.worlds {
            out.extend_from_slice(&(*frame as i32).to_le_bytes());
        }
        let w = &self.worlds;
        if let Some((_, bad)) = w.iter().find(|(_, v)| v.lights.len() != nlight) {
            return Err(WarpError::Lights {
                world: bad.lights.len(),
                scene: nlight,
            }
            .into());
        }
        f32s(&mut out, &mut w.iter().flat_map(|(_, v)| v.cam_pos.map(f)));
        f32s(&mut out, &mut w.iter().flat_map(|(_, v)| v.cam_mat.map(f)));
        let lights = |g: fn(&LightState) -> [f64; 3]| {
            w.iter()
                .flat_map(move |(_, v)| v.lights.iter().flat_map(move |l| g(l).map(f)))
        };
        f32s(&mut out, &mut lights(|l| l.pos));
        f32s(&mut out, &mut lights(|l| l.dir));
        f32s(&mut out, &mut lights(|l| l.diffuse));
        f32s(
            &mut out,
            &mut w.iter().flat_map(|(_, v)| v.head_ambient.map(f)),
        );
        f32s(
            &mut out,
            &mut w.iter().flat_map(|(_, v)| v.head_diffuse.map(f)),
        );
        for (_, v) in w {
            out.extend_from_slice(&v.table_matid.to_le_bytes());
        }
        f32s(&mut out, &mut w.iter().flat_map(|(_, v)| v.table_rgba));
        Ok(out)
    }
}

/// The field of view of `view` in `model` (degrees): the camera's, or the free camera's.
pub fn view_fovy(model: &MjModel, view: CameraView) -> f64 {
    match view {
        CameraView::Fixed(id) => model.cam_fovy()[id],
        CameraView::Orbit { .. } => f64::from(model.ffi().vis.global.fovy),
    }
}

/// The distinct fields of view of `views`, in first-seen order: the slots to open.
pub fn view_slots(model: &MjModel, views: impl IntoIterator<Item = CameraView>) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::new();
    for v in views {
        let f = view_fovy(model, v);
        if !out.contains(&f) {
            out.push(f);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_free_camera_looks_at_its_point_from_its_distance() {
        let model = MjModel::from_xml_string("<mujoco><worldbody/></mujoco>").unwrap();
        let data = MjData::new(&model);
        let view = CameraView::Orbit {
            lookat: [0.0, 0.0, 1.0],
            distance: 2.0,
            azimuth: 90.0,
            elevation: -30.0,
        };
        let (pos, mat, fovy) = camera_pose(&model, &data, view);
        // Backwards (column 2) points from the look-at point to the camera.
        let back = [mat[2], mat[5], mat[8]];
        for i in 0..3 {
            let expect = ([0.0, 0.0, 1.0][i] + 2.0 * back[i] - pos[i]).abs();
            assert!(expect < 1e-12, "{pos:?} {back:?}");
        }
        assert!(pos[2] > 1.0, "elevation -30 looks down from above");
        assert_eq!(fovy, f64::from(model.ffi().vis.global.fovy));
        // Orthonormal.
        let col = |c: usize| [mat[c], mat[3 + c], mat[6 + c]];
        for a in 0..3 {
            for b in 0..3 {
                let d: f64 = (0..3).map(|i| col(a)[i] * col(b)[i]).sum();
                assert!((d - f64::from(u8::from(a == b))).abs() < 1e-12);
            }
        }
    }
}
