//! The episode model: named per-frame arrays ([`FrameArray`]) of one task, with their
//! frame rate, prompt and source, as every stage passes them on.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::error::{CoreError, Location};
use crate::layout::{ArmSetup, DEXJOCO_FPS};
use crate::rotation::action_to_rotvec;
use crate::task_spec::TaskSpec;

/// A per-frame array: `len()` frames of `width` values each, row-major.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameArray {
    width: usize,
    data: Vec<f64>,
}

impl FrameArray {
    /// Wraps a flat row-major buffer; it must hold a whole number of frames.
    pub fn new(width: usize, data: Vec<f64>) -> Result<Self, CoreError> {
        if width == 0 || !data.len().is_multiple_of(width) {
            return Err(CoreError::Ragged {
                at: Location::default(),
                len: data.len(),
                width,
            });
        }
        Ok(Self { width, data })
    }

    /// An array of `frames` rows of zeros.
    pub fn zeros(frames: usize, width: usize) -> Self {
        Self {
            width,
            data: vec![0.0; frames * width],
        }
    }

    /// Builds an array from rows, which must all have the same width (at least 1).
    pub fn from_rows<R: AsRef<[f64]>>(rows: &[R]) -> Result<Self, CoreError> {
        let width = rows.first().map_or(1, |r| r.as_ref().len());
        let mut data = Vec::with_capacity(rows.len() * width);
        for (i, r) in rows.iter().enumerate() {
            let r = r.as_ref();
            if r.len() != width {
                return Err(CoreError::Width {
                    at: Location::default().frame(i),
                    expected: width,
                    found: r.len(),
                });
            }
            data.extend_from_slice(r);
        }
        Self::new(width, data)
    }

    /// Values per frame.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.data.len() / self.width
    }

    /// True when there are no frames.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Frame `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.data[i * self.width..(i + 1) * self.width]
    }

    /// Frame `i`, mutable.
    pub fn row_mut(&mut self, i: usize) -> &mut [f64] {
        &mut self.data[i * self.width..(i + 1) * self.width]
    }

    /// Iterates over frames.
    pub fn rows(&self) -> impl ExactSizeIterator<Item = &[f64]> {
        self.data.chunks_exact(self.width)
    }

    /// The flat row-major buffer.
    pub fn as_slice(&self) -> &[f64] {
        &self.data
    }

    /// The flat buffer, consumed.
    pub fn into_vec(self) -> Vec<f64> {
        self.data
    }
}

/// The first frame the reference converter keeps (the end of an episode's static leading
/// frames): the first `i` with `action[i] != action[i + 1]`, plus one when `action[i]` is
/// all zeros. An episode whose action never changes keeps all its frames (start 0).
/// `action` is the selected action; with `float32` its values are compared rounded to
/// float32, as the reference's LeRobot writer loads them (its Zarr writer compares them
/// as recorded). `convert` skips these frames; `stats --dataset` counts them.
pub fn first_moving_frame(action: &FrameArray, float32: bool) -> usize {
    let n = action.len();
    let differ = |i: usize| {
        let (a, b) = (action.row(i), action.row(i + 1));
        if float32 {
            a.iter().zip(b).any(|(x, y)| *x as f32 != *y as f32)
        } else {
            a != b
        }
    };
    let Some(i) = (0..n.saturating_sub(1)).find(|&i| differ(i)) else {
        return 0;
    };
    if action.row(i).iter().all(|v| *v == 0.0) {
        (i + 1).min(n.saturating_sub(1))
    } else {
        i
    }
}

/// Every frame where `convert` may start an episode's kept frames (its static leading
/// frames cut): [`first_moving_frame`] of `action` and of `action_rotvec`, as recorded and
/// rounded to float32, the first frame left out. Augment makes these frames keyframes
/// of its videos so that `convert` cuts there by stream copy.
pub fn possible_cuts(episode: &Episode) -> Vec<usize> {
    let mut cuts: Vec<usize> = [Episode::ACTION, Episode::ACTION_ROTVEC]
        .into_iter()
        .filter_map(|name| episode.array(name))
        .flat_map(|a| [false, true].map(|float32| first_moving_frame(a, float32)))
        .filter(|&k| k > 0)
        .collect();
    cuts.sort_unstable();
    cuts.dedup();
    cuts
}

/// One camera of an episode: its name and where its frames are stored.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct CameraStream {
    /// Camera name in the scene, e.g. `front` or `handcam_rgb`.
    pub name: String,
    /// RGB video, relative to the episode folder (e.g. `videos/front.mp4`).
    pub video: Option<PathBuf>,
    /// Depth in metres (`videos/<camera>_depth.npz`), when recorded.
    pub depth: Option<PathBuf>,
}

/// One demonstration or replay: metadata and named per-frame arrays.
///
/// The standard arrays are `action` (T x 23/46), `action_rotvec` (T x 22/44),
/// `state` (T x S, S per task) and `timestamp` (T x 1). Frame k holds the observation
/// before step k and the action applied at step k.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Episode {
    /// Stable id, unique within a store.
    pub id: String,
    /// Task id, e.g. `click_mouse`.
    pub task: String,
    /// Language instruction.
    pub prompt: String,
    /// Frames per second the data is labelled with (30 for DexJoCo).
    pub fps: f64,
    /// Named per-frame arrays.
    pub arrays: BTreeMap<String, FrameArray>,
    /// Cameras and their stored frames.
    pub cameras: Vec<CameraStream>,
}

impl Episode {
    /// Name of the action array.
    pub const ACTION: &'static str = "action";
    /// Name of the rotation-vector action array.
    pub const ACTION_ROTVEC: &'static str = "action_rotvec";
    /// Name of the state array.
    pub const STATE: &'static str = "state";
    /// Name of the timestamp array.
    pub const TIMESTAMP: &'static str = "timestamp";
    /// The objects' state at every frame, as the simulator has it before the frame's
    /// action: each of the task spec's state objects' pose (or position), then the poses
    /// its reset derives from them (a mouse pad, Hanoi's disks), then the table offset `dh`
    /// ([`crate::TaskSpec::environment_state_names`]): what `state`'s privileged columns
    /// hold at reset, made current and complete. Recorded by the stages that simulate
    /// (augment, generate, scripted, eval).
    pub const ENVIRONMENT_STATE: &'static str = "environment_state";

    /// Number of frames (of `action`, or of any array when there is no action).
    pub fn len(&self) -> usize {
        self.arrays
            .get(Self::ACTION)
            .or_else(|| self.arrays.values().next())
            .map_or(0, FrameArray::len)
    }

    /// True when the episode has no frames.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// An array by name.
    pub fn array(&self, name: &str) -> Option<&FrameArray> {
        self.arrays.get(name)
    }

    /// `timestamp = k / fps` for every frame.
    pub fn regular_timestamps(frames: usize, fps: f64) -> FrameArray {
        FrameArray {
            width: 1,
            data: (0..frames).map(|k| k as f64 / fps).collect(),
        }
    }

    /// A recorded rollout of `spec`'s task at DexJoCo's 30 Hz: `actions[t]` executed
    /// from `states[t]`, with regular timestamps, the task's prompt and `action_rotvec`
    /// derived from the actions; no cameras.
    pub fn from_rollout(
        id: String,
        spec: &TaskSpec,
        actions: &[Vec<f64>],
        states: &[Vec<f64>],
    ) -> Result<Self, CoreError> {
        let arrays = BTreeMap::from([
            (Self::ACTION.to_owned(), FrameArray::from_rows(actions)?),
            (Self::STATE.to_owned(), FrameArray::from_rows(states)?),
            (
                Self::TIMESTAMP.to_owned(),
                Self::regular_timestamps(actions.len(), DEXJOCO_FPS),
            ),
        ]);
        let mut ep = Self {
            id,
            task: spec.id.clone(),
            prompt: spec.prompt.clone(),
            fps: DEXJOCO_FPS,
            arrays,
            cameras: Vec::new(),
        };
        ep.compute_action_rotvec(spec.setup)?;
        Ok(ep)
    }

    /// Stores `rows` (one per frame, all of one width) as the array `name`, replacing any
    /// present; no rows store an empty array of width 0.
    pub fn insert_rows(&mut self, name: &str, rows: &[Vec<f64>]) -> Result<(), CoreError> {
        let array = if rows.is_empty() {
            FrameArray::zeros(0, 0)
        } else {
            FrameArray::from_rows(rows)?
        };
        self.arrays.insert(name.to_owned(), array);
        Ok(())
    }

    /// Computes `action_rotvec` from `action` (per arm, normalized quaternion to rotation
    /// vector; zero quaternion to zero) and stores it, replacing any present.
    pub fn compute_action_rotvec(&mut self, setup: ArmSetup) -> Result<(), CoreError> {
        let action = self
            .arrays
            .get(Self::ACTION)
            .ok_or_else(|| CoreError::Length {
                at: Location::episode(&self.id).field(Self::ACTION),
                expected: self.len(),
                found: 0,
            })?;
        self.check_width(Self::ACTION, setup.action_dim())?;
        let mut out = FrameArray::zeros(action.len(), setup.action_rotvec_dim());
        for i in 0..action.len() {
            action_to_rotvec(action.row(i), out.row_mut(i));
        }
        self.arrays.insert(Self::ACTION_ROTVEC.into(), out);
        Ok(())
    }

    /// Checks that the named array has `width` columns.
    pub fn check_width(&self, name: &str, width: usize) -> Result<(), CoreError> {
        let at = Location::episode(&self.id).field(name);
        match self.arrays.get(name) {
            Some(a) if a.width() == width => Ok(()),
            Some(a) => Err(CoreError::Width {
                at,
                expected: width,
                found: a.width(),
            }),
            None => Err(CoreError::Width {
                at,
                expected: width,
                found: 0,
            }),
        }
    }

    /// Checks that every array has the same number of frames and only finite values.
    pub fn check_consistent(&self) -> Result<(), CoreError> {
        let n = self.len();
        for (name, a) in &self.arrays {
            if a.len() != n {
                return Err(CoreError::Length {
                    at: Location::episode(&self.id).field(name),
                    expected: n,
                    found: a.len(),
                });
            }
            if let Some(pos) = a.as_slice().iter().position(|v| !v.is_finite()) {
                return Err(CoreError::NotFinite {
                    at: Location::episode(&self.id)
                        .field(format!("{name}[{}]", pos % a.width()))
                        .frame(pos / a.width()),
                    value: a.as_slice()[pos],
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn episode(action: Vec<Vec<f64>>) -> Episode {
        let n = action.len();
        let mut arrays = BTreeMap::new();
        arrays.insert(
            Episode::ACTION.into(),
            FrameArray::from_rows(&action).unwrap(),
        );
        arrays.insert(
            Episode::TIMESTAMP.into(),
            Episode::regular_timestamps(n, 30.0),
        );
        Episode {
            id: "ep0".into(),
            task: "click_mouse".into(),
            prompt: "click the mouse".into(),
            fps: 30.0,
            arrays,
            cameras: vec![],
        }
    }

    #[test]
    fn rotvec_is_computed_per_arm() {
        let mut row = vec![0.0; 46];
        row[3] = 1.0; // right arm identity
        row[23 + 3] = 0.0; // left arm: 180 degrees about z
        row[23 + 6] = 1.0;
        row[7] = 0.5; // a hand value is copied
        let mut ep = episode(vec![row]);
        ep.compute_action_rotvec(ArmSetup::Bimanual).unwrap();
        let rv = ep.array(Episode::ACTION_ROTVEC).unwrap().row(0);
        assert_eq!(rv.len(), 44);
        assert_eq!(&rv[3..6], &[0.0, 0.0, 0.0]);
        assert_eq!(rv[6], 0.5);
        assert!((rv[22 + 5] - std::f64::consts::PI).abs() < 1e-15);
    }

    #[test]
    fn consistency_names_field_and_frame() {
        let mut ep = episode(vec![vec![0.0; 23], vec![0.0; 23]]);
        ep.arrays.get_mut(Episode::ACTION).unwrap().row_mut(1)[4] = f64::NAN;
        let err = ep.check_consistent().unwrap_err().to_string();
        assert!(
            err.contains("episode 'ep0'") && err.contains("action[4]") && err.contains("frame 1"),
            "{err}"
        );
        let err = ep.check_width(Episode::ACTION, 46).unwrap_err().to_string();
        assert!(
            err.contains("expected 46") && err.contains("found 23"),
            "{err}"
        );
    }

    #[test]
    fn ragged_buffers_are_refused() {
        assert!(FrameArray::new(3, vec![0.0; 7]).is_err());
        assert_eq!(FrameArray::new(3, vec![0.0; 9]).unwrap().len(), 3);
    }
}
