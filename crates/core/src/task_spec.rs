//! Task specifications as data: `schemas/tasks/<task_id>.toml`.
//!
//! A [`TaskSpec`] says everything a simulator needs to know about one DexJoCo task
//! besides the scene file itself: the robot setup, prompt and cameras, the layout of
//! the privileged part of the state and how to restore it, the randomization ranges,
//! the step cap, and the success and failure conditions.
//!
//! Conditions are a graph of named [`Node`]s, each one reusable primitive of one of the
//! four constraint kinds of the DexJoCo paper (g_pose, g_joint, g_contact, g_seq) or a
//! named scene mechanic (the nail that sinks, the iPad keypad, the Hanoi stacks). A node
//! refers to other nodes by name (`"on_pad"`) or to a named output of a node
//! (`"nail.depth"`); the simulator evaluates them in dependency order after every step.
//!
//! The files are read strictly (unknown keys are errors) and then checked by
//! [`TaskSpec::validate`]; the JSON Schema `schemas/task-spec.schema.json` is generated
//! from these types, so schema and reader cannot disagree.

use std::collections::{BTreeMap, BTreeSet};

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::layout::{ArmSetup, ArrayLayout, POSE_DIM};

/// One DexJoCo task.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TaskSpec {
    /// Task id, e.g. `click_mouse` (the file is `<id>.toml`).
    pub id: String,
    /// Name in the paper, e.g. `Click Mouse`.
    pub name: String,
    /// One arm or two.
    pub setup: ArmSetup,
    /// File name of the reference scene (in a scene pack such as DexJoCo's `xmls/`).
    pub scene: String,
    /// The language instruction.
    pub prompt: String,
    /// Episode length limit in control steps.
    pub step_cap: usize,
    /// Camera streams: raw key and scene camera.
    pub cameras: Vec<CameraSpec>,
    /// How the environment resets the robot.
    #[serde(default)]
    pub reset: ResetSpec,
    /// The table and its height offset `dh`.
    #[serde(default)]
    pub table: TableSpec,
    /// The privileged part of the state and how a recorded one is restored.
    pub state: StateSpec,
    /// Object placement randomization, in draw order.
    #[serde(default)]
    pub placement: Vec<Placement>,
    /// Dynamics randomization ("rand-dynamics"), in draw order.
    #[serde(default)]
    pub dynamics: Vec<DynamicsRandomization>,
    /// The condition graph: node name -> node.
    pub nodes: BTreeMap<String, Node>,
    /// The node whose value is the task's success.
    pub success: String,
    /// The node whose value ends the episode as a failure, if the task has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
}

/// A camera stream of the task.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// Key of the stream in the raw data (`front`, `ego`, `wrist_left`...).
    pub key: String,
    /// Camera name in the scene.
    pub camera: String,
}

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
    /// Named visual leg geoms (legs are visual only; unnamed legs are left alone).
    #[serde(default)]
    pub legs: Vec<String>,
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

/// A point in the world, read from the simulation.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum PointRef {
    /// A framepos sensor (lagged one substep).
    Sensor(String),
    /// A site's world position.
    Site(String),
    /// A body's world position.
    Body(String),
    /// A geom's world position.
    Geom(String),
}

/// A frame (orientation) in the world.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum FrameRef {
    /// A site's frame.
    Site(String),
    /// A body's frame.
    Body(String),
    /// A geom's frame.
    Geom(String),
}

/// A joint value.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum JointRef {
    /// A jointpos sensor (lagged one substep, as the reference reads it).
    Sensor(String),
    /// The joint's current qpos.
    Qpos(String),
}

/// A comparison with a constant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Cmp {
    /// >
    Gt,
    /// >=
    Ge,
    /// <
    Lt,
    /// <=
    Le,
    /// |x| <
    AbsLt,
    /// |x| <=
    AbsLe,
}

impl Cmp {
    /// `x op value`.
    pub fn holds(self, x: f64, value: f64) -> bool {
        match self {
            Self::Gt => x > value,
            Self::Ge => x >= value,
            Self::Lt => x < value,
            Self::Le => x <= value,
            Self::AbsLt => x.abs() < value,
            Self::AbsLe => x.abs() <= value,
        }
    }
}

/// `op value`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Threshold {
    /// The comparison.
    pub op: Cmp,
    /// The constant.
    pub value: f64,
}

/// A set of geoms, for contact conditions.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum GeomSet {
    /// Any geom.
    Any,
    /// These geoms.
    Geoms(Vec<String>),
    /// Every geom of a body and its descendants.
    Subtree(String),
    /// Every geom not in a body's subtree.
    OutsideSubtree(String),
}

/// Whether a box's bounds are in world axes or the origin body's axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum BoxAxes {
    /// World axes (the origin's orientation is ignored).
    #[default]
    World,
    /// The origin frame's axes (R^T (p - origin)).
    Origin,
}

/// A Hanoi disk of the [`Node::HanoiTowers`] mechanic.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct HanoiDisk {
    /// Disk name (`large`...), largest first.
    pub name: String,
    /// Its free joint.
    pub joint: String,
}

/// A keypad button of the [`Node::Keypad`] mechanic.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct KeypadButton {
    /// The digit.
    pub digit: u8,
    /// The button's geom.
    pub geom: String,
}

/// One node of the condition graph. Every node has a boolean value each step; some have
/// named outputs too (see [`Node::outputs`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Node {
    // ---- g_pose ----
    /// `point - center` lies in a cylinder along a world axis: the radial distance is
    /// <= radius and the axial component lies in `along` (inclusive).
    PointInCylinder {
        /// The point tested.
        point: PointRef,
        /// The cylinder's centre.
        center: PointRef,
        /// The cylinder axis (world).
        #[serde(default)]
        axis: Axis,
        /// Radius.
        radius: f64,
        /// Axial range [lo, hi] relative to the centre.
        along: [f64; 2],
    },
    /// `point - origin` (in world or origin axes) lies in [min, max] (inclusive).
    PointInBox {
        /// The point tested.
        point: PointRef,
        /// The box's origin frame.
        origin: FrameRef,
        /// Axes of the bounds.
        #[serde(default)]
        axes: BoxAxes,
        /// Lower bounds.
        min: [f64; 3],
        /// Upper bounds.
        max: [f64; 3],
    },
    /// The point lies in the axis-aligned box spanned by sites (componentwise min/max).
    PointInSiteBox {
        /// The point tested.
        point: PointRef,
        /// The sites spanning the box.
        sites: Vec<String>,
    },
    /// Every site is at least `min_rise` above its height at reset.
    HeightAboveReset {
        /// The sites.
        sites: Vec<String>,
        /// Rise needed.
        min_rise: f64,
    },
    /// `point.z >= reference.z + min_offset`; the reference is read at reset when
    /// `reference_at_reset`.
    AboveReference {
        /// The point tested.
        point: PointRef,
        /// The reference point.
        reference: PointRef,
        /// Height above the reference.
        min_offset: f64,
        /// Read the reference once, at reset.
        #[serde(default)]
        reference_at_reset: bool,
    },
    /// A frame's axis is within `max_angle_deg` of a world direction.
    AxisAlignment {
        /// The frame.
        frame: FrameRef,
        /// Which of its axes.
        axis: Axis,
        /// The world direction.
        target: [f64; 3],
        /// Largest angle, degrees.
        max_angle_deg: f64,
    },
    // ---- g_joint ----
    /// `joint op value`.
    JointThreshold {
        /// The joint.
        joint: JointRef,
        /// The comparison.
        op: Cmp,
        /// The constant.
        value: f64,
    },
    /// The joint exceeds its value at reset by more than `delta`.
    JointAboveReset {
        /// The joint.
        joint: JointRef,
        /// The margin.
        delta: f64,
    },
    /// A latch with hysteresis: cleared when `clear` holds (checked first), else set when
    /// `set` holds, else unchanged.
    JointHysteresis {
        /// The joint.
        joint: JointRef,
        /// Condition that sets the latch.
        set: Threshold,
        /// Condition that clears it.
        clear: Threshold,
        /// Value at reset.
        #[serde(default)]
        initial: bool,
    },
    // ---- g_contact ----
    /// Some contact pairs a geom of `a` with a geom of `b` (either order), with
    /// distance <= max_dist when given.
    Contact {
        /// One side.
        a: GeomSet,
        /// The other side.
        b: GeomSet,
        /// Largest contact distance.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        max_dist: Option<f64>,
    },
    // ---- g_seq and logic ----
    /// All inputs true.
    All {
        /// Inputs.
        of: Vec<String>,
    },
    /// Some input true.
    Any {
        /// Inputs.
        of: Vec<String>,
    },
    /// Input false.
    Not {
        /// Input.
        of: String,
    },
    /// The input was true on this and the previous `steps - 1` steps (the count resets
    /// on a false step). Output `count`.
    Held {
        /// Input.
        of: String,
        /// Steps needed.
        steps: u32,
    },
    /// The input is true now and was false on the previous step (false at reset).
    RisingEdge {
        /// Input.
        of: String,
    },
    /// The input is false now and was true on the previous step.
    FallingEdge {
        /// Input.
        of: String,
    },
    /// Counts the steps on which the input is true (use an edge as input to count
    /// events); true once the count reaches `at_least`. Output `count`.
    Counter {
        /// Input.
        of: String,
        /// Count needed.
        at_least: u32,
    },
    /// Set when `set` is true, cleared when `clear` is true (set wins), else kept.
    Latch {
        /// Input that sets.
        set: String,
        /// Input that clears.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        clear: Option<String>,
    },
    /// Ordered events: the rising edges of `events` must come in list order; true once
    /// all came. An out-of-order rising edge sets output `wrong` (latched) and restarts.
    /// Outputs `index`, `wrong`.
    Sequence {
        /// Events in the order they must happen.
        events: Vec<String>,
    },
    /// A numeric output of another node compared with a constant, e.g. `nail.depth`.
    ValueThreshold {
        /// `node.output`.
        of: String,
        /// The comparison.
        op: Cmp,
        /// The constant.
        value: f64,
    },
    // ---- scene mechanics ----
    /// The nail sinks under fast hammer blows. After each substep the face height is
    /// sampled (vz = dz / vz_divisor, last `window` samples kept); after the step, if a
    /// hammer geom touches a nail geom and min(vz) < `min_vz`, depth grows by
    /// `gain * min(max_scale, |vz| / |min_vz|)` up to `max_depth`, and the nail mocap
    /// moves down to its reset height minus depth (then mj_forward). Value: depth grew
    /// this step. Output `depth`.
    NailSinking {
        /// Hammer geoms that can strike.
        hammer: Vec<String>,
        /// Nail geoms that can be struck.
        nail: Vec<String>,
        /// The geom whose height gives the strike speed.
        face: String,
        /// The nail's mocap body.
        nail_body: String,
        /// Samples kept.
        window: usize,
        /// Divisor of the per-substep height change (the reference divides by 0.02).
        vz_divisor: f64,
        /// Speed threshold (negative = down).
        min_vz: f64,
        /// Depth per hit at unit scale.
        gain: f64,
        /// Largest scale of one hit.
        max_scale: f64,
        /// Largest depth.
        max_depth: f64,
    },
    /// A keypad entered by fingertips: a button registers when a finger geom starts
    /// touching it (new presses handled in ascending geom id order); the right digit
    /// advances, a wrong one sets `failed` and restarts. Value: unlocked (latched).
    /// Outputs `failed`, `index`.
    Keypad {
        /// Buttons.
        buttons: Vec<KeypadButton>,
        /// Finger geoms that press.
        fingers: Vec<String>,
        /// The password digits.
        password: Vec<u8>,
    },
    /// Tower of Hanoi bookkeeping: disks assigned to posts, stack order and tolerances,
    /// the goal stack and the illegal-state counter. Value: the goal configuration
    /// holds. Output `illegal`.
    HanoiTowers {
        /// The base body.
        base: String,
        /// Post sites A, B, C.
        posts: Vec<String>,
        /// Disks, largest first.
        disks: Vec<HanoiDisk>,
        /// Top of the base above the base origin.
        top_offset: f64,
        /// Disk half-height.
        half_height: f64,
        /// Largest 6-D free-joint speed of a static disk.
        static_speed: f64,
        /// Largest xy distance of a disk to the post it is on.
        post_radius: f64,
        /// A disk not on a post is on the table below top + this.
        table_margin: f64,
        /// Stack xy tolerance.
        xy_tol: f64,
        /// Stack z tolerance.
        z_tol: f64,
        /// Index of the goal post.
        goal_post: usize,
        /// Steps of one illegal reason that end the episode.
        illegal_steps: u32,
    },
}

impl Node {
    /// Named outputs (besides the value) other nodes may read as `name.output`.
    pub fn outputs(&self) -> &'static [&'static str] {
        match self {
            Self::Held { .. } | Self::Counter { .. } => &["count"],
            Self::Sequence { .. } => &["index", "wrong"],
            Self::NailSinking { .. } => &["depth"],
            Self::Keypad { .. } => &["failed", "index"],
            Self::HanoiTowers { .. } => &["illegal"],
            _ => &[],
        }
    }

    /// Names of the nodes (or `node.output`s) this node reads.
    pub fn inputs(&self) -> Vec<&str> {
        match self {
            Self::All { of } | Self::Any { of } => of.iter().map(String::as_str).collect(),
            Self::Not { of }
            | Self::Held { of, .. }
            | Self::RisingEdge { of }
            | Self::FallingEdge { of }
            | Self::Counter { of, .. }
            | Self::ValueThreshold { of, .. } => vec![of.as_str()],
            Self::Latch { set, clear } => {
                let mut v = vec![set.as_str()];
                v.extend(clear.as_deref());
                v
            }
            Self::Sequence { events } => events.iter().map(String::as_str).collect(),
            _ => Vec::new(),
        }
    }

    /// The constraint kind of the paper this node belongs to.
    pub fn kind(&self) -> ConstraintKind {
        match self {
            Self::PointInCylinder { .. }
            | Self::PointInBox { .. }
            | Self::PointInSiteBox { .. }
            | Self::HeightAboveReset { .. }
            | Self::AboveReference { .. }
            | Self::AxisAlignment { .. } => ConstraintKind::Pose,
            Self::JointThreshold { .. }
            | Self::JointAboveReset { .. }
            | Self::JointHysteresis { .. } => ConstraintKind::Joint,
            Self::Contact { .. } => ConstraintKind::Contact,
            Self::NailSinking { .. } | Self::Keypad { .. } | Self::HanoiTowers { .. } => {
                ConstraintKind::Mechanic
            }
            _ => ConstraintKind::Seq,
        }
    }
}

/// The four constraint kinds of the DexJoCo paper, plus scene mechanics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ConstraintKind {
    /// g_seq: time, order, counting, logic.
    Seq,
    /// g_pose: object poses.
    Pose,
    /// g_joint: articulation state.
    Joint,
    /// g_contact: touching geoms.
    Contact,
    /// A named scene mechanic (nail, keypad, Hanoi).
    Mechanic,
}

/// Errors of a task spec.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TaskSpecError {
    /// The TOML is malformed or does not match the types.
    #[error("task spec '{file}': {message}")]
    Parse {
        /// File or label.
        file: String,
        /// What is wrong.
        message: String,
    },
    /// The spec parses but is inconsistent.
    #[error("task spec '{task}': {message}")]
    Invalid {
        /// Task id.
        task: String,
        /// What is wrong.
        message: String,
    },
}

/// An embedded spec is checked by this crate's tests, so failing here is a build defect.
fn parse_builtin(id: &str, text: &str) -> TaskSpec {
    TaskSpec::from_toml_str(text, &format!("schemas/tasks/{id}.toml"))
        .unwrap_or_else(|e| panic!("embedded task spec {id}: {e}"))
}

/// The task specs shipped in `schemas/tasks/`, embedded at build time: (task id, TOML).
pub const BUILTIN_SPEC_FILES: [(&str, &str); 11] = {
    macro_rules! specs {
        ($($id:literal),*) => {
            [$(($id, include_str!(concat!("../../../schemas/tasks/", $id, ".toml")))),*]
        };
    }
    specs!(
        "bimanual_assembly",
        "bimanual_hanoi",
        "bimanual_microwave_cook",
        "bimanual_photograph",
        "bimanual_unlock_ipad",
        "click_mouse",
        "fold_glasses",
        "hammer_nail",
        "pick_bucket",
        "pinch_tongs",
        "water_plant"
    )
};

impl TaskSpec {
    /// The shipped spec of a task (embedded from `schemas/tasks/`); `None` for an unknown
    /// id.
    pub fn builtin(id: &str) -> Option<Self> {
        let (id, text) = BUILTIN_SPEC_FILES.iter().find(|(t, _)| *t == id)?;
        Some(parse_builtin(id, text))
    }

    /// Every shipped spec, sorted by task id.
    pub fn builtin_all() -> Vec<Self> {
        BUILTIN_SPEC_FILES
            .iter()
            .map(|(id, text)| parse_builtin(id, text))
            .collect()
    }

    /// The built-in specs, with those in `dir` (when given) replacing the built-in ones of
    /// the same id or adding tasks; sorted by task id.
    pub fn builtin_and(dir: Option<&std::path::Path>) -> Result<Vec<Self>, TaskSpecError> {
        let mut all: std::collections::BTreeMap<String, Self> = Self::builtin_all()
            .into_iter()
            .map(|s| (s.id.clone(), s))
            .collect();
        if let Some(dir) = dir {
            for s in Self::load_dir(dir)? {
                all.insert(s.id.clone(), s);
            }
        }
        Ok(all.into_values().collect())
    }

    /// Parses a spec from TOML text (strict: unknown keys are errors) and validates it.
    pub fn from_toml_str(text: &str, label: &str) -> Result<Self, TaskSpecError> {
        let spec: Self = toml::from_str(text).map_err(|e| TaskSpecError::Parse {
            file: label.into(),
            message: e.to_string(),
        })?;
        spec.validate()?;
        Ok(spec)
    }

    /// Reads and validates one spec file.
    pub fn from_file(path: &std::path::Path) -> Result<Self, TaskSpecError> {
        let text = std::fs::read_to_string(path).map_err(|e| TaskSpecError::Parse {
            file: path.display().to_string(),
            message: e.to_string(),
        })?;
        let spec = Self::from_toml_str(&text, &path.display().to_string())?;
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        if stem != spec.id {
            return Err(spec.invalid(format!(
                "file '{}' must be named after the task id",
                path.display()
            )));
        }
        Ok(spec)
    }

    /// Reads every `*.toml` spec of a folder, sorted by task id.
    pub fn load_dir(dir: &std::path::Path) -> Result<Vec<Self>, TaskSpecError> {
        let entries = std::fs::read_dir(dir).map_err(|e| TaskSpecError::Parse {
            file: dir.display().to_string(),
            message: e.to_string(),
        })?;
        let mut paths: Vec<_> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        paths.sort();
        paths.iter().map(|p| Self::from_file(p)).collect()
    }

    /// The JSON Schema of the spec file (what `schemas/task-spec.schema.json` holds).
    pub fn json_schema() -> serde_json::Value {
        let schema = schemars::schema_for!(TaskSpec);
        serde_json::to_value(schema).expect("a schema is JSON")
    }

    /// The full state layout: proprioception, then the objects' poses, then `dh`.
    pub fn state_layout(&self) -> ArrayLayout {
        let mut l = self.setup.proprio_layout();
        for o in &self.state.objects {
            l.push(format!("{}.pose", o.name), o.source.width());
        }
        l.push("dh", 1);
        l
    }

    /// The node names in an order where every node comes after its inputs: scene
    /// mechanics first, then depth-first by name.
    pub fn evaluation_order(&self) -> Result<Vec<String>, TaskSpecError> {
        let mut order = Vec::new();
        let mut done = BTreeSet::new();
        let mut visiting = BTreeSet::new();
        // Scene mechanics first: they may move objects (the nail) that other nodes read.
        let mechanics = self
            .nodes
            .iter()
            .filter(|(_, n)| n.kind() == ConstraintKind::Mechanic);
        let others = self
            .nodes
            .iter()
            .filter(|(_, n)| n.kind() != ConstraintKind::Mechanic);
        for (name, _) in mechanics.chain(others) {
            self.visit(name, &mut done, &mut visiting, &mut order)?;
        }
        Ok(order)
    }

    fn visit(
        &self,
        name: &str,
        done: &mut BTreeSet<String>,
        visiting: &mut BTreeSet<String>,
        order: &mut Vec<String>,
    ) -> Result<(), TaskSpecError> {
        if done.contains(name) {
            return Ok(());
        }
        if !visiting.insert(name.to_owned()) {
            return Err(self.invalid(format!("node '{name}' depends on itself")));
        }
        let node = self
            .nodes
            .get(name)
            .ok_or_else(|| self.invalid(format!("unknown node '{name}'")))?;
        for input in node.inputs() {
            let base = input.split('.').next().unwrap_or(input);
            self.visit(base, done, visiting, order)?;
        }
        visiting.remove(name);
        done.insert(name.to_owned());
        order.push(name.to_owned());
        Ok(())
    }

    fn invalid(&self, message: String) -> TaskSpecError {
        TaskSpecError::Invalid {
            task: self.id.clone(),
            message,
        }
    }

    /// Checks what the types cannot: references between nodes resolve (and outputs
    /// exist), the graph has no cycle, the state width matches the layout, objects named
    /// by placements and derived poses exist, ranges and counts are sensible.
    pub fn validate(&self) -> Result<(), TaskSpecError> {
        let check_ref = |r: &str| -> Result<(), TaskSpecError> {
            let (base, out) = match r.split_once('.') {
                Some((b, o)) => (b, Some(o)),
                None => (r, None),
            };
            let node = self
                .nodes
                .get(base)
                .ok_or_else(|| self.invalid(format!("reference to unknown node '{base}'")))?;
            if let Some(o) = out
                && !node.outputs().contains(&o)
            {
                return Err(self.invalid(format!(
                    "node '{base}' has no output '{o}' (it has: {})",
                    node.outputs().join(", ")
                )));
            }
            Ok(())
        };
        for (name, node) in &self.nodes {
            if name.contains('.') || name.is_empty() {
                return Err(self.invalid(format!("bad node name '{name}'")));
            }
            for input in node.inputs() {
                check_ref(input)?;
            }
            if let Node::ValueThreshold { of, .. } = node
                && !of.contains('.')
            {
                return Err(self.invalid(format!(
                    "node '{name}': value_threshold needs 'node.output', got '{of}'"
                )));
            }
            self.validate_node(name, node)?;
        }
        check_ref(&self.success)?;
        if let Some(f) = &self.failure {
            check_ref(f)?;
        }
        self.evaluation_order()?;

        let width = self.state_layout().width();
        if width != self.state.width {
            return Err(self.invalid(format!(
                "state width {} does not match the layout ({width})",
                self.state.width
            )));
        }
        let objects: BTreeSet<&str> = self.state.objects.iter().map(|o| o.name.as_str()).collect();
        if objects.len() != self.state.objects.len() {
            return Err(self.invalid("duplicate state object names".into()));
        }
        for p in &self.placement {
            if !objects.contains(p.object.as_str()) {
                return Err(self.invalid(format!("placement of unknown object '{}'", p.object)));
            }
            if p.yaw_deg < 0.0 || p.axes[0] == p.axes[1] {
                return Err(self.invalid(format!("bad placement of '{}'", p.object)));
            }
        }
        for d in &self.state.derived {
            if let Some(f) = &d.from
                && !objects.contains(f.as_str())
            {
                return Err(self.invalid(format!("derived pose from unknown object '{f}'")));
            }
        }
        if let Some(h) = &self.reset.hand_qpos
            && h.len() != crate::layout::HAND_DOF
        {
            return Err(self.invalid(format!("reset.hand_qpos has {} values, not 16", h.len())));
        }
        if self.step_cap == 0 || self.cameras.is_empty() {
            return Err(self.invalid("step_cap and cameras must not be empty".into()));
        }
        for d in &self.dynamics {
            let r = match d {
                DynamicsRandomization::MassScale { range, .. }
                | DynamicsRandomization::FrictionlossUniform { range, .. }
                | DynamicsRandomization::FrictionlossScale { range, .. }
                | DynamicsRandomization::StiffnessScale { range, .. } => range,
            };
            if r[0] > r[1] || r[0] < 0.0 {
                return Err(self.invalid(format!("bad dynamics range {r:?}")));
            }
        }
        Ok(())
    }

    fn validate_node(&self, name: &str, node: &Node) -> Result<(), TaskSpecError> {
        let bad = |what: &str| Err(self.invalid(format!("node '{name}': {what}")));
        match node {
            Node::PointInCylinder { radius, along, .. }
                if *radius <= 0.0 || along[0] > along[1] =>
            {
                bad("radius must be > 0 and along ordered")
            }
            Node::PointInBox { min, max, .. } if (0..3).any(|i| min[i] > max[i]) => {
                bad("min must be <= max")
            }
            Node::PointInSiteBox { sites, .. } | Node::HeightAboveReset { sites, .. }
                if sites.is_empty() =>
            {
                bad("needs sites")
            }
            Node::AxisAlignment {
                target,
                max_angle_deg,
                ..
            } if target.iter().all(|v| *v == 0.0) || !(0.0..=180.0).contains(max_angle_deg) => {
                bad("target must be non-zero and the angle in [0, 180]")
            }
            Node::All { of } | Node::Any { of } if of.is_empty() => bad("needs inputs"),
            Node::Held { steps, .. } if *steps == 0 => bad("steps must be >= 1"),
            Node::Sequence { events } if events.is_empty() => bad("needs events"),
            Node::NailSinking {
                window,
                vz_divisor,
                min_vz,
                ..
            } if *window == 0 || *vz_divisor <= 0.0 || *min_vz >= 0.0 => {
                bad("window >= 1, vz_divisor > 0 and min_vz < 0")
            }
            Node::Keypad {
                buttons, password, ..
            } if password.is_empty()
                || password
                    .iter()
                    .any(|d| !buttons.iter().any(|b| b.digit == *d)) =>
            {
                bad("every password digit needs a button")
            }
            Node::HanoiTowers {
                posts,
                disks,
                goal_post,
                ..
            } if posts.is_empty() || disks.is_empty() || *goal_post >= posts.len() => {
                bad("needs posts, disks and a goal post among them")
            }
            _ => Ok(()),
        }
    }

    /// Every scene name the spec refers to, by kind (`joint`, `body`, `site`, `geom`,
    /// `camera`, `sensor`), for checking against a scene.
    pub fn scene_names(&self) -> Vec<(NameKind, String)> {
        let mut out = Vec::new();
        let mut push = |k: NameKind, n: &str| out.push((k, n.to_owned()));
        for c in &self.cameras {
            push(NameKind::Camera, &c.camera);
        }
        push(NameKind::Body, &self.table.body);
        push(NameKind::Site, &self.table.top_site);
        for l in &self.table.legs {
            push(NameKind::Geom, l);
        }
        for j in self.reset.joint_qpos.keys() {
            push(NameKind::Joint, j);
        }
        let pose = |s: &PoseSource, push: &mut dyn FnMut(NameKind, &str)| match s {
            PoseSource::FreeJoint(n) => push(NameKind::Joint, n),
            PoseSource::Body(n) | PoseSource::Mocap(n) | PoseSource::BodyPosition(n) => {
                push(NameKind::Body, n)
            }
            PoseSource::GeomLocal(n) => push(NameKind::Geom, n),
        };
        for o in &self.state.objects {
            pose(&o.source, &mut push);
        }
        for d in &self.state.derived {
            pose(&d.target, &mut push);
        }
        for d in &self.dynamics {
            match d {
                DynamicsRandomization::MassScale { body, .. } => push(NameKind::Body, body),
                DynamicsRandomization::FrictionlossUniform { joint, .. }
                | DynamicsRandomization::FrictionlossScale { joint, .. }
                | DynamicsRandomization::StiffnessScale { joint, .. } => {
                    push(NameKind::Joint, joint)
                }
            }
        }
        let point = |p: &PointRef, push: &mut dyn FnMut(NameKind, &str)| match p {
            PointRef::Sensor(n) => push(NameKind::Sensor, n),
            PointRef::Site(n) => push(NameKind::Site, n),
            PointRef::Body(n) => push(NameKind::Body, n),
            PointRef::Geom(n) => push(NameKind::Geom, n),
        };
        let frame = |f: &FrameRef, push: &mut dyn FnMut(NameKind, &str)| match f {
            FrameRef::Site(n) => push(NameKind::Site, n),
            FrameRef::Body(n) => push(NameKind::Body, n),
            FrameRef::Geom(n) => push(NameKind::Geom, n),
        };
        let joint = |j: &JointRef, push: &mut dyn FnMut(NameKind, &str)| match j {
            JointRef::Sensor(n) => push(NameKind::Sensor, n),
            JointRef::Qpos(n) => push(NameKind::Joint, n),
        };
        let geoms = |g: &GeomSet, push: &mut dyn FnMut(NameKind, &str)| match g {
            GeomSet::Any => {}
            GeomSet::Geoms(v) => v.iter().for_each(|n| push(NameKind::Geom, n)),
            GeomSet::Subtree(b) | GeomSet::OutsideSubtree(b) => push(NameKind::Body, b),
        };
        for node in self.nodes.values() {
            match node {
                Node::PointInCylinder {
                    point: p, center, ..
                } => {
                    point(p, &mut push);
                    point(center, &mut push);
                }
                Node::PointInBox {
                    point: p, origin, ..
                } => {
                    point(p, &mut push);
                    frame(origin, &mut push);
                }
                Node::PointInSiteBox { point: p, sites } => {
                    point(p, &mut push);
                    sites.iter().for_each(|s| push(NameKind::Site, s));
                }
                Node::HeightAboveReset { sites, .. } => {
                    sites.iter().for_each(|s| push(NameKind::Site, s))
                }
                Node::AboveReference {
                    point: p,
                    reference,
                    ..
                } => {
                    point(p, &mut push);
                    point(reference, &mut push);
                }
                Node::AxisAlignment { frame: f, .. } => frame(f, &mut push),
                Node::JointThreshold { joint: j, .. }
                | Node::JointAboveReset { joint: j, .. }
                | Node::JointHysteresis { joint: j, .. } => joint(j, &mut push),
                Node::Contact { a, b, .. } => {
                    geoms(a, &mut push);
                    geoms(b, &mut push);
                }
                Node::NailSinking {
                    hammer,
                    nail,
                    face,
                    nail_body,
                    ..
                } => {
                    hammer
                        .iter()
                        .chain(nail)
                        .chain([face])
                        .for_each(|g| push(NameKind::Geom, g));
                    push(NameKind::Body, nail_body);
                }
                Node::Keypad {
                    buttons, fingers, ..
                } => {
                    buttons.iter().for_each(|b| push(NameKind::Geom, &b.geom));
                    fingers.iter().for_each(|g| push(NameKind::Geom, g));
                }
                Node::HanoiTowers {
                    base, posts, disks, ..
                } => {
                    push(NameKind::Body, base);
                    posts.iter().for_each(|s| push(NameKind::Site, s));
                    disks.iter().for_each(|d| push(NameKind::Joint, &d.joint));
                }
                _ => {}
            }
        }
        out.sort();
        out.dedup();
        out
    }
}

/// Kinds of scene names a spec refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum NameKind {
    /// A joint.
    Joint,
    /// A body.
    Body,
    /// A site.
    Site,
    /// A geom.
    Geom,
    /// A camera.
    Camera,
    /// A sensor.
    Sensor,
    /// An actuator.
    Actuator,
}

impl NameKind {
    /// Lower-case name, e.g. `geom`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Joint => "joint",
            Self::Body => "body",
            Self::Site => "site",
            Self::Geom => "geom",
            Self::Camera => "camera",
            Self::Sensor => "sensor",
            Self::Actuator => "actuator",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn schemas_dir() -> PathBuf {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../schemas")
    }

    /// The 11 DexJoCo tasks with their state widths (dexjoco-raw-format.md).
    const TASKS: [(&str, usize); 11] = [
        ("bimanual_assembly", 61),
        ("bimanual_hanoi", 50),
        ("bimanual_microwave_cook", 61),
        ("bimanual_photograph", 61),
        ("bimanual_unlock_ipad", 61),
        ("click_mouse", 31),
        ("fold_glasses", 38),
        ("hammer_nail", 38),
        ("pick_bucket", 38),
        ("pinch_tongs", 31),
        ("water_plant", 38),
    ];

    #[test]
    fn the_embedded_specs_are_the_folder() {
        let from_dir = TaskSpec::load_dir(&schemas_dir().join("tasks")).unwrap();
        let embedded = TaskSpec::builtin_all();
        assert_eq!(embedded, from_dir);
        assert_eq!(TaskSpec::builtin("click_mouse").unwrap(), from_dir[5]);
        assert!(TaskSpec::builtin("no_such_task").is_none());
        // A folder of specs replaces built-in ones by id and adds new ones.
        let tmp = tempfile::tempdir().unwrap();
        let mut text = BUILTIN_SPEC_FILES[5]
            .1
            .replace("prompt = \"", "prompt = \"Changed. ");
        std::fs::write(tmp.path().join("click_mouse.toml"), &text).unwrap();
        text = text.replace("id = \"click_mouse\"", "id = \"my_click\"");
        std::fs::write(tmp.path().join("my_click.toml"), &text).unwrap();
        let all = TaskSpec::builtin_and(Some(tmp.path())).unwrap();
        assert_eq!(all.len(), 12);
        let mine = all.iter().find(|s| s.id == "click_mouse").unwrap();
        assert!(mine.prompt.starts_with("Changed. "), "{}", mine.prompt);
        assert!(all.iter().any(|s| s.id == "my_click"));
        assert_eq!(TaskSpec::builtin_and(None).unwrap(), from_dir);
    }

    #[test]
    fn every_task_spec_loads_and_validates() {
        let specs = TaskSpec::load_dir(&schemas_dir().join("tasks")).unwrap();
        let ids: Vec<_> = specs
            .iter()
            .map(|s| (s.id.as_str(), s.state.width))
            .collect();
        assert_eq!(ids, TASKS);
        for s in &specs {
            let order = s.evaluation_order().unwrap();
            assert_eq!(order.len(), s.nodes.len(), "{}", s.id);
            // Inputs come before the nodes that read them.
            for (i, name) in order.iter().enumerate() {
                for input in s.nodes[name].inputs() {
                    let base = input.split('.').next().unwrap();
                    let j = order.iter().position(|n| n == base).unwrap();
                    assert!(j < i, "{}: {base} after {name}", s.id);
                }
            }
            assert!(!s.scene_names().is_empty());
            // The four constraint kinds and mechanics appear as primitives, never as code.
            let cap = if s.setup == ArmSetup::Bimanual {
                46
            } else {
                23
            };
            assert_eq!(s.setup.proprio_dim(), cap);
        }
        // Some fixed facts.
        let mouse = specs.iter().find(|s| s.id == "click_mouse").unwrap();
        assert_eq!(mouse.step_cap, 1200);
        assert_eq!(mouse.state_layout().get("mouse.pose").unwrap().start, 23);
        let hanoi = specs.iter().find(|s| s.id == "bimanual_hanoi").unwrap();
        assert_eq!(hanoi.state_layout().get("dh").unwrap().start, 49);
    }

    /// The committed JSON Schema is exactly the one generated from the serde types, so
    /// schema and reader agree. Regenerate with `DEXJOCO_UPDATE_SCHEMA=1 cargo test`.
    #[test]
    fn json_schema_matches_the_types() {
        // Keys sorted, whatever serde_json's `preserve_order` feature (which other crates
        // of the workspace turn on) makes of map order.
        fn sorted(v: &serde_json::Value) -> serde_json::Value {
            match v {
                serde_json::Value::Object(m) => {
                    let mut keys: Vec<&String> = m.keys().collect();
                    keys.sort();
                    serde_json::Value::Object(
                        keys.into_iter()
                            .map(|k| (k.clone(), sorted(&m[k])))
                            .collect(),
                    )
                }
                serde_json::Value::Array(a) => {
                    serde_json::Value::Array(a.iter().map(sorted).collect())
                }
                other => other.clone(),
            }
        }
        let path = schemas_dir().join("task-spec.schema.json");
        let generated = sorted(&TaskSpec::json_schema());
        if std::env::var_os("DEXJOCO_UPDATE_SCHEMA").is_some() {
            std::fs::write(
                &path,
                serde_json::to_string_pretty(&generated).unwrap() + "\n",
            )
            .unwrap();
        }
        let committed: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap_or_default())
                .unwrap_or_default();
        assert!(
            committed == generated,
            "{} is stale: run DEXJOCO_UPDATE_SCHEMA=1 cargo test -p dexjoco-core",
            path.display()
        );
        // Every spec, as JSON, uses only properties the schema declares at the top level.
        let schema = TaskSpec::json_schema();
        let props = schema["properties"].as_object().unwrap();
        for s in TaskSpec::load_dir(&schemas_dir().join("tasks")).unwrap() {
            let v = serde_json::to_value(&s).unwrap();
            for k in v.as_object().unwrap().keys() {
                assert!(props.contains_key(k), "{}: {k} not in the schema", s.id);
            }
            for r in schema["required"].as_array().unwrap() {
                assert!(
                    v.get(r.as_str().unwrap()).is_some(),
                    "{}: {r} missing",
                    s.id
                );
            }
            // Round trip: what we write reads back the same.
            let back: TaskSpec = serde_json::from_value(v).unwrap();
            assert_eq!(back, s);
        }
    }

    fn minimal(extra: &str) -> String {
        format!(
            r#"
id = "t"
name = "T"
setup = "single_arm"
scene = "s.xml"
prompt = "p"
step_cap = 10
success = "done"
cameras = [{{ key = "front", camera = "front" }}]
[state]
width = 24
objects = []
{extra}
"#
        )
    }

    #[test]
    fn unknown_keys_and_bad_references_are_refused() {
        let ok = minimal(
            "[nodes.done]\nkind = \"all\"\nof = [\"x\"]\n[nodes.x]\nkind = \"not\"\nof = \"done2\"\n[nodes.done2]\nkind = \"latch\"\nset = \"x\"\n",
        );
        // x -> done2 -> x is a cycle.
        let e = TaskSpec::from_toml_str(&ok, "t").unwrap_err().to_string();
        assert!(e.contains("depends on itself"), "{e}");

        let typo = minimal("[nodes.done]\nkind = \"held\"\nof = \"done\"\nstep = 3\n");
        let e = TaskSpec::from_toml_str(&typo, "t").unwrap_err().to_string();
        assert!(e.contains("step"), "{e}");

        let unknown = minimal("[nodes.done]\nkind = \"not\"\nof = \"nothing\"\n");
        let e = TaskSpec::from_toml_str(&unknown, "t")
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown node 'nothing'"), "{e}");

        let port = minimal(
            "[nodes.a]\nkind = \"held\"\nof = \"b\"\nsteps = 2\n[nodes.b]\nkind = \"not\"\nof = \"a.depth\"\n[nodes.done]\nkind = \"not\"\nof = \"a\"\n",
        );
        let e = TaskSpec::from_toml_str(&port, "t").unwrap_err().to_string();
        assert!(e.contains("no output 'depth'"), "{e}");

        let width = minimal("[nodes.done]\nkind = \"joint_threshold\"\njoint = { qpos = \"j\" }\nop = \"gt\"\nvalue = 1.0\n")
            .replace("width = 24", "width = 23");
        let e = TaskSpec::from_toml_str(&width, "t")
            .unwrap_err()
            .to_string();
        assert!(e.contains("state width"), "{e}");

        let top = minimal(
            "[nodes.done]\nkind = \"any\"\nof = [\"e\"]\n[nodes.e]\nkind = \"joint_threshold\"\njoint = { qpos = \"j\" }\nop = \"gt\"\nvalue = 1.0\n",
        ) + "\n[extra]\nx = 1\n";
        assert!(TaskSpec::from_toml_str(&top, "t").is_err());
    }
}
