//! The robot's array layouts (action, `action_rotvec`, proprioception) for one and two
//! arms, column names, and the Allegro hand's ranges.

use serde::{Deserialize, Serialize};

/// Allegro hand joints per hand (ff, mf, rf, th x j0..j3).
pub const HAND_DOF: usize = 16;
/// A pose in an action or state: xyz + quaternion wxyz.
pub const POSE_DIM: usize = 7;
/// A pose in `action_rotvec`: xyz + rotation vector.
pub const ROTVEC_POSE_DIM: usize = 6;

/// Frames per second DexJoCo data is labelled with.
pub const DEXJOCO_FPS: f64 = 30.0;

/// Steps a replay of a recording may go on past its end, repeating its last action, to
/// reach its success (`--extend-steps` of augment and generate): one second at 30 Hz. The
/// DexJoCo recorder stops on the step that first succeeds, so a replay that drifts by a
/// step or two (MuJoCo versions, CPUs) would otherwise never succeed within it.
pub const DEFAULT_EXTEND_STEPS: usize = 30;

/// The table height offset range (m) the reset draws dh from.
pub const TABLE_OFFSET_RANGE: (f64, f64) = (0.0, 0.05);

/// Allegro hand position-actuator control ranges (rad), in ff, mf, rf, th order (j0..j3
/// each). The left hand's recorded order rf, mf, ff, th has the same ranges per column
/// because the three fingers share theirs.
pub const HAND_CTRL_RANGES: [(f64, f64); HAND_DOF] = {
    const BASE: (f64, f64) = (-0.47, 0.47);
    const PROX: (f64, f64) = (-0.196, 1.61);
    const MED: (f64, f64) = (-0.174, 1.709);
    const DIST: (f64, f64) = (-0.227, 1.618);
    [
        BASE,
        PROX,
        MED,
        DIST,
        BASE,
        PROX,
        MED,
        DIST,
        BASE,
        PROX,
        MED,
        DIST,
        (0.263, 1.396),
        (-0.105, 1.163),
        (-0.189, 1.644),
        (-0.162, 1.719),
    ]
};

/// Which robot a task uses: one arm and hand, or two.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ArmSetup {
    /// One Panda + Allegro (action 23, action_rotvec 22, proprioception 23).
    SingleArm,
    /// Two Panda + Allegro (action 46 = [right23, left23], action_rotvec 44).
    Bimanual,
}

impl ArmSetup {
    /// Number of arms.
    pub fn arms(self) -> usize {
        match self {
            Self::SingleArm => 1,
            Self::Bimanual => 2,
        }
    }

    /// Width of `action`: per arm [x, y, z, qw, qx, qy, qz, hand16].
    pub fn action_dim(self) -> usize {
        self.arms() * (POSE_DIM + HAND_DOF)
    }

    /// Width of `action_rotvec`: per arm [x, y, z, rx, ry, rz, hand16].
    pub fn action_rotvec_dim(self) -> usize {
        self.arms() * (ROTVEC_POSE_DIM + HAND_DOF)
    }

    /// Width of the proprioceptive part of `state` (what policies train on).
    pub fn proprio_dim(self) -> usize {
        self.action_dim()
    }

    /// Arm names in recorded order.
    pub fn arm_names(self) -> &'static [&'static str] {
        match self {
            Self::SingleArm => &["arm"],
            Self::Bimanual => &["right", "left"],
        }
    }

    /// Named slices of `action`, in the recorded order [right23, left23].
    pub fn action_layout(self) -> ArrayLayout {
        let mut l = ArrayLayout::default();
        for arm in self.arm_names() {
            l.push(format!("{arm}.pos"), 3);
            l.push(format!("{arm}.quat_wxyz"), 4);
            l.push(format!("{arm}.hand"), HAND_DOF);
        }
        l
    }

    /// Named slices of `action_rotvec`.
    pub fn action_rotvec_layout(self) -> ArrayLayout {
        let mut l = ArrayLayout::default();
        for arm in self.arm_names() {
            l.push(format!("{arm}.pos"), 3);
            l.push(format!("{arm}.rotvec"), 3);
            l.push(format!("{arm}.hand"), HAND_DOF);
        }
        l
    }

    /// Named slices of the proprioceptive part of `state`: TCP poses first, then hands
    /// (the left hand's joints in rf, mf, ff, th order).
    pub fn proprio_layout(self) -> ArrayLayout {
        let mut l = ArrayLayout::default();
        for arm in self.arm_names() {
            l.push(format!("{arm}.tcp_pos"), 3);
            l.push(format!("{arm}.tcp_quat_wxyz"), 4);
        }
        for arm in self.arm_names() {
            l.push(format!("{arm}.hand_qpos"), HAND_DOF);
        }
        l
    }
}

/// One named run of columns in a per-frame array.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct FieldSlice {
    /// Name, e.g. `right.quat_wxyz` or `mouse.pose`.
    pub name: String,
    /// First column.
    pub start: usize,
    /// Number of columns.
    pub len: usize,
}

/// The columns of a per-frame array, as consecutive named slices.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ArrayLayout {
    /// The slices, in column order, without gaps.
    pub fields: Vec<FieldSlice>,
}

impl ArrayLayout {
    /// Appends a slice of `len` columns after the last one.
    pub fn push(&mut self, name: impl Into<String>, len: usize) -> &mut Self {
        let start = self.width();
        self.fields.push(FieldSlice {
            name: name.into(),
            start,
            len,
        });
        self
    }

    /// Total number of columns.
    pub fn width(&self) -> usize {
        self.fields.last().map_or(0, |f| f.start + f.len)
    }

    /// The slice with this name.
    pub fn get(&self, name: &str) -> Option<&FieldSlice> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// The name of a column, as `slice[i]`, e.g. `right.hand[3]`.
    pub fn column_name(&self, column: usize) -> String {
        self.fields
            .iter()
            .find(|f| column >= f.start && column < f.start + f.len)
            .map_or_else(
                || format!("[{column}]"),
                |f| format!("{}[{}]", f.name, column - f.start),
            )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn widths_match_the_dexjoco_layouts() {
        assert_eq!(ArmSetup::SingleArm.action_dim(), 23);
        assert_eq!(ArmSetup::Bimanual.action_dim(), 46);
        assert_eq!(ArmSetup::SingleArm.action_rotvec_dim(), 22);
        assert_eq!(ArmSetup::Bimanual.action_rotvec_dim(), 44);
        assert_eq!(ArmSetup::Bimanual.action_layout().width(), 46);
        assert_eq!(ArmSetup::Bimanual.action_rotvec_layout().width(), 44);
        assert_eq!(ArmSetup::Bimanual.proprio_layout().width(), 46);
        let p = ArmSetup::Bimanual.proprio_layout();
        // [0:7] right TCP, [7:14] left TCP, [14:30] right hand, [30:46] left hand.
        assert_eq!(p.get("left.tcp_pos").unwrap().start, 7);
        assert_eq!(p.get("right.hand_qpos").unwrap().start, 14);
        assert_eq!(p.get("left.hand_qpos").unwrap().start, 30);
        let a = ArmSetup::Bimanual.action_layout();
        assert_eq!(a.get("left.pos").unwrap().start, 23);
        assert_eq!(a.column_name(26), "left.quat_wxyz[0]");
    }
}
