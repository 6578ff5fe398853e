//! The 11 DexJoCo tasks as data: setup, state width and its privileged part, step cap,
//! prompt and cameras. Stages validate episodes against this table until the per-task
//! specs (`schemas/tasks/`) feed the same facts; the shape of [`TaskInfo`] is meant to be
//! filled from them.

use serde::Serialize;

use crate::layout::{ArmSetup, ArrayLayout, HAND_DOF};

/// What a run of privileged state columns holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PrivilegedKind {
    /// An object's reset-time pose: position xyz + quaternion wxyz (7 values).
    Pose,
    /// A position only: xyz (3 values).
    Position,
    /// The table height offset dh (1 value), in [0, 0.05] m.
    TableOffset,
}

impl PrivilegedKind {
    /// Number of columns.
    pub fn width(self) -> usize {
        match self {
            Self::Pose => 7,
            Self::Position => 3,
            Self::TableOffset => 1,
        }
    }
}

/// One named run of privileged state columns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct PrivilegedField {
    /// Name, e.g. `mouse` or `dh`.
    pub name: &'static str,
    /// What it holds.
    pub kind: PrivilegedKind,
}

/// Facts about one task that validation and conversion need.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TaskInfo {
    /// Task id, e.g. `click_mouse`.
    pub id: &'static str,
    /// One arm or two.
    pub setup: ArmSetup,
    /// Width S of `state`.
    pub state_dim: usize,
    /// The privileged part of `state` after the proprioception, in column order.
    pub privileged: &'static [PrivilegedField],
    /// Maximum number of control steps of an episode.
    pub step_cap: usize,
    /// The language instruction.
    pub prompt: &'static str,
    /// Camera streams of the raw recordings.
    pub cameras: &'static [&'static str],
}

/// The table height offset range (m).
pub const TABLE_OFFSET_RANGE: (f64, f64) = (0.0, 0.05);

/// Frames per second DexJoCo data is labelled with.
pub const DEXJOCO_FPS: f64 = 30.0;

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

const fn pose(name: &'static str) -> PrivilegedField {
    PrivilegedField {
        name,
        kind: PrivilegedKind::Pose,
    }
}

const DH: PrivilegedField = PrivilegedField {
    name: "dh",
    kind: PrivilegedKind::TableOffset,
};

const SINGLE_CAMS: &[&str] = &["front", "ego_left", "ego_right", "wrist"];
const BIMANUAL_CAMS: &[&str] = &["ego", "wrist_left", "wrist_right"];

/// The 11 tasks.
pub const TASKS: &[TaskInfo] = &[
    TaskInfo {
        id: "hammer_nail",
        setup: ArmSetup::SingleArm,
        state_dim: 38,
        privileged: &[pose("hammer"), pose("nail"), DH],
        step_cap: 1000,
        prompt: "Use the hammer to drive the nail into the wooden board.",
        cameras: SINGLE_CAMS,
    },
    TaskInfo {
        id: "click_mouse",
        setup: ArmSetup::SingleArm,
        state_dim: 31,
        privileged: &[pose("mouse"), DH],
        step_cap: 1200,
        prompt: "Move the mouse to the purple mouse pad and click the left mouse button.",
        cameras: SINGLE_CAMS,
    },
    TaskInfo {
        id: "pick_bucket",
        setup: ArmSetup::SingleArm,
        state_dim: 38,
        privileged: &[pose("bucket"), pose("food"), DH],
        step_cap: 1200,
        prompt: "Place the boxed food into the bucket and then lift the bucket.",
        cameras: SINGLE_CAMS,
    },
    TaskInfo {
        id: "pinch_tongs",
        setup: ArmSetup::SingleArm,
        state_dim: 31,
        privileged: &[pose("tongs"), DH],
        step_cap: 1000,
        prompt: "Grasp the tongs and perform three consecutive open-close motions.",
        cameras: SINGLE_CAMS,
    },
    TaskInfo {
        id: "fold_glasses",
        setup: ArmSetup::SingleArm,
        state_dim: 38,
        privileged: &[pose("glasses"), pose("case"), DH],
        step_cap: 1200,
        prompt: "Fold the glasses and place them into the case.",
        cameras: SINGLE_CAMS,
    },
    TaskInfo {
        id: "water_plant",
        setup: ArmSetup::SingleArm,
        state_dim: 38,
        privileged: &[pose("spray"), pose("plant"), DH],
        step_cap: 1000,
        prompt: "Grasp the watering can and apply water to the plant.",
        cameras: &["front", "wrist"],
    },
    TaskInfo {
        id: "bimanual_unlock_ipad",
        setup: ArmSetup::Bimanual,
        state_dim: 61,
        privileged: &[pose("stand"), pose("ipad"), DH],
        step_cap: 1200,
        prompt: "Grasp the iPad and enter the password 123 to unlock the device.",
        cameras: BIMANUAL_CAMS,
    },
    TaskInfo {
        id: "bimanual_hanoi",
        setup: ArmSetup::Bimanual,
        state_dim: 50,
        privileged: &[
            PrivilegedField {
                name: "base",
                kind: PrivilegedKind::Position,
            },
            DH,
        ],
        step_cap: 1500,
        prompt: "Execute the final two moves of the three-level Tower of Hanoi: move the medium disk \
                 from the middle peg to the right peg with the right hand, then move the small disk \
                 from the left peg to the right peg with the left hand.",
        cameras: BIMANUAL_CAMS,
    },
    TaskInfo {
        id: "bimanual_assembly",
        setup: ArmSetup::Bimanual,
        state_dim: 61,
        privileged: &[pose("tray"), pose("peg"), DH],
        step_cap: 1500,
        prompt: "Grasp the tray with the left hand and the peg with the right hand, then insert the \
                 peg into the hole.",
        cameras: BIMANUAL_CAMS,
    },
    TaskInfo {
        id: "bimanual_microwave_cook",
        setup: ArmSetup::Bimanual,
        state_dim: 61,
        privileged: &[pose("hot_dog"), pose("microwave"), DH],
        step_cap: 1100,
        prompt: "Open the microwave door, place the food inside the microwave, close the door, and \
                 press the start button.",
        cameras: BIMANUAL_CAMS,
    },
    TaskInfo {
        id: "bimanual_photograph",
        setup: ArmSetup::Bimanual,
        state_dim: 61,
        privileged: &[pose("camera"), pose("logo"), DH],
        step_cap: 1000,
        prompt: "Grasp the camera with the left hand, align it with the logo, and press the shutter \
                 button with the right hand.",
        cameras: BIMANUAL_CAMS,
    },
];

/// The task with this id.
pub fn task_info(id: &str) -> Option<&'static TaskInfo> {
    TASKS.iter().find(|t| t.id == id)
}

impl TaskInfo {
    /// Named slices of `state`: proprioception, then each privileged field.
    pub fn state_layout(&self) -> ArrayLayout {
        let mut l = self.setup.proprio_layout();
        for f in self.privileged {
            l.push(f.name, f.kind.width());
        }
        l
    }

    /// Column of the table height offset dh in `state` (the last one).
    pub fn dh_column(&self) -> usize {
        self.state_dim - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_cover_the_state_width() {
        assert_eq!(TASKS.len(), 11);
        for t in TASKS {
            assert_eq!(t.state_layout().width(), t.state_dim, "{}", t.id);
            assert_eq!(t.state_layout().get("dh").unwrap().start, t.dh_column());
            assert_eq!(t.state_layout().column_name(t.dh_column()), "dh[0]");
        }
        assert_eq!(task_info("bimanual_hanoi").unwrap().state_dim, 50);
        assert!(task_info("nope").is_none());
    }
}
