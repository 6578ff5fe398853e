//! The robot reset, the table, the privileged part of the state (objects and derived
//! poses), and object placement and dynamics randomization of a [`TaskSpec`](super::TaskSpec).

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::layout::POSE_DIM;

/// How the arm target is initialised at reset (dexjoco-task-semantics A.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ArmTargetInit {
    /// Mocap position and orientation = the home TCP pose.
    #[default]
    Pose,
    /// Only the position; the mocap orientation stays the scene's (0, 1, 0, 0).
    PositionOnly,
}

/// Reset of the robot.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ResetSpec {
    /// How the arm target starts.
    #[serde(default)]
    pub arm_target: ArmTargetInit,
    /// Home thumb j0 is written as float32(0.263) unless this is set (microwave: exact).
    #[serde(default)]
    pub exact_thumb: bool,
    /// A non-home hand pose written to the hand qpos and hand controls (click_mouse), in
    /// the action's hand order.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hand_qpos: Option<Vec<f64>>,
    /// Object joints set at reset, e.g. the tongs hinge opened past its range (0.3).
    #[serde(default)]
    pub joint_qpos: BTreeMap<String, f64>,
}

/// How the visual table legs follow `dh`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum LegStyle {
    /// Half-length + dh.
    #[default]
    Extend,
    /// Centre - dh/2, half-length + dh/2 (microwave, iPad).
    Half,
}

/// The table.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TableSpec {
    /// The table body (its z is set to dh).
    #[serde(default = "default_table_body")]
    pub body: String,
    /// The site on the table top.
    #[serde(default = "default_table_top")]
    pub top_site: String,
    /// Named visual leg geoms (legs are visual only; unnamed legs are left alone unless
    /// `cylinder_legs`).
    #[serde(default)]
    pub legs: Vec<String>,
    /// Every visual cylinder geom of the table body is a leg too (named or not): the
    /// DexJoCo reference environments' rule, whose scenes leave the legs unnamed.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub cylinder_legs: bool,
    /// How legs follow dh.
    #[serde(default)]
    pub leg_style: LegStyle,
}

fn default_table_body() -> String {
    "table".into()
}

fn default_table_top() -> String {
    "table_top".into()
}

impl Default for TableSpec {
    fn default() -> Self {
        Self {
            body: default_table_body(),
            top_site: default_table_top(),
            legs: Vec::new(),
            cylinder_legs: false,
            leg_style: LegStyle::Extend,
        }
    }
}

/// Where an object's pose lives in the model.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum PoseSource {
    /// The 7 qpos values of a free joint.
    FreeJoint(String),
    /// A static body's position and orientation (model body_pos / body_quat).
    Body(String),
    /// A mocap body's pose.
    Mocap(String),
    /// A geom's pose relative to its body (model geom_pos / geom_quat).
    GeomLocal(String),
    /// Only a static body's position (3 values).
    BodyPosition(String),
}

impl PoseSource {
    /// Values this object takes in the state vector.
    pub fn width(&self) -> usize {
        match self {
            Self::BodyPosition(_) => 3,
            _ => POSE_DIM,
        }
    }

    /// The model name it refers to.
    pub fn name(&self) -> &str {
        match self {
            Self::FreeJoint(n)
            | Self::Body(n)
            | Self::Mocap(n)
            | Self::GeomLocal(n)
            | Self::BodyPosition(n) => n,
        }
    }
}

/// One object of the privileged state: its reset-time pose.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StateObject {
    /// Name in the state layout, e.g. `mouse`.
    pub name: String,
    /// Where the pose is read from and restored to.
    pub source: PoseSource,
    /// Restore only the position (the orientation keeps the reset value: iPad).
    #[serde(default)]
    pub restore_position_only: bool,
}

/// The vertical placement of a derived pose.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum ZRule {
    /// Keep the z the pose has (plus nothing).
    Keep,
    /// z = value + dh.
    DhPlus(f64),
    /// z = table top z + value.
    TableTopPlus(f64),
    /// z = z of the source object + offset z.
    FromSource,
}

/// A pose derived from another object: written on restore after the recorded objects
/// (mouse pad from the mouse, target region from the logo, Hanoi disks from the base,
/// monitor height). When the target is itself a state object (the iPad on its stand),
/// the pose is used when placing objects at reset, and a restore keeps the recorded one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DerivedPose {
    /// What is written.
    pub target: PoseSource,
    /// A state object whose position (plus `offset`) gives x, y; none keeps x, y.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from: Option<String>,
    /// Offset added to the source position.
    #[serde(default)]
    pub offset: [f64; 3],
    /// How z is set.
    pub z: ZRule,
    /// Orientation written (wxyz), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub quat: Option<[f64; 4]>,
}

/// The privileged part of the state vector and its restore.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StateSpec {
    /// Objects, in state order, after the proprioceptive part.
    pub objects: Vec<StateObject>,
    /// Poses derived from the restored objects, written after them, in order.
    #[serde(default)]
    pub derived: Vec<DerivedPose>,
    /// Where the hand joints of the state come from.
    #[serde(default)]
    pub hand_source: HandSource,
    /// Total state width (checked against the layout).
    pub width: usize,
}

/// Where the hand joint values of the state are read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum HandSource {
    /// The jointpos sensors (lagged one substep).
    #[default]
    Sensor,
    /// The current qpos (hammer_nail).
    Qpos,
}

/// A world or local axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Axis {
    /// x.
    X,
    /// y.
    Y,
    /// z.
    #[default]
    Z,
}

impl Axis {
    /// Index 0, 1, 2.
    pub fn index(self) -> usize {
        match self {
            Self::X => 0,
            Self::Y => 1,
            Self::Z => 2,
        }
    }
}

/// Object placement randomization: `uniform(low, high)` draws (numpy argument order;
/// `high < low` occurs and is kept), then optionally a yaw.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Placement {
    /// The state object placed.
    pub object: String,
    /// Which two coordinates are drawn (default x, y; the photograph logo draws y, z).
    #[serde(default = "default_axes")]
    pub axes: [Axis; 2],
    /// `low` argument of the draw.
    pub low: [f64; 2],
    /// `high` argument of the draw.
    pub high: [f64; 2],
    /// Yaw drawn uniformly in +-yaw_deg, applied as qz * quat0.
    #[serde(default)]
    pub yaw_deg: f64,
    /// The yaw is drawn before the position (microwave hot dog).
    #[serde(default)]
    pub yaw_first: bool,
    /// The height rule of the placed pose.
    pub z: ZRule,
    /// Base orientation (wxyz) the yaw is applied to.
    #[serde(default = "identity_quat")]
    pub quat: [f64; 4],
}

fn default_axes() -> [Axis; 2] {
    [Axis::X, Axis::Y]
}

fn identity_quat() -> [f64; 4] {
    [1.0, 0.0, 0.0, 0.0]
}

/// Dynamics randomization (off in replay).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum DynamicsRandomization {
    /// body_mass *= U(range) (inertia kept).
    MassScale {
        /// Body.
        body: String,
        /// Multiplier range.
        range: [f64; 2],
    },
    /// dof_frictionloss = U(range).
    FrictionlossUniform {
        /// Joint.
        joint: String,
        /// Value range.
        range: [f64; 2],
    },
    /// dof_frictionloss *= U(range) (of the original value).
    FrictionlossScale {
        /// Joint.
        joint: String,
        /// Multiplier range.
        range: [f64; 2],
    },
    /// jnt_stiffness *= U(range).
    StiffnessScale {
        /// Joint.
        joint: String,
        /// Multiplier range.
        range: [f64; 2],
    },
}
