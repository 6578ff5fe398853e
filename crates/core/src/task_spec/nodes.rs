//! The condition graph's node types: references into the simulation (points, frames,
//! joints, geom sets) and the [`Node`] primitives of the four constraint kinds of the
//! DexJoCo paper plus the scene mechanics.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::Axis;

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

/// A hand of the robot, for [`Node::Grasp`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Hand {
    /// The one hand of a single-arm robot.
    Single,
    /// The left hand of a bimanual robot.
    Left,
    /// The right hand of a bimanual robot.
    Right,
}

impl Hand {
    fn suffix(self) -> &'static str {
        match self {
            Self::Single => "",
            Self::Left => "_left",
            Self::Right => "_right",
        }
    }

    /// The root bodies of this hand's fingers, thumb last: the Allegro hand's `ff_base`,
    /// `mf_base`, `rf_base`, `th_base` (with `_left` / `_right` on a bimanual robot), as
    /// both the reference robot and the built-in one name them; a finger is its root's
    /// subtree.
    pub fn fingers(self) -> [String; 4] {
        ["ff", "mf", "rf", "th"].map(|f| format!("{f}_base{}", self.suffix()))
    }

    /// The palm body (`allegro_palm`, suffixed likewise); the palm is its own geoms.
    pub fn palm(self) -> String {
        format!("allegro_palm{}", self.suffix())
    }

    /// The arm a subtask reading this hand belongs to.
    pub fn arm(self) -> super::SubtaskArm {
        match self {
            Self::Single => super::SubtaskArm::Single,
            Self::Left => super::SubtaskArm::Left,
            Self::Right => super::SubtaskArm::Right,
        }
    }
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
    /// An object grasped by a hand: at least `min_fingers` of the index, middle and ring
    /// fingers touch a geom of `object`, and the thumb or the palm does too, opposing them
    /// (a pinch, a wrap): the opposition tells a grasp from a push. A finger is every link
    /// of it (its root body's subtree), the palm its body's own geoms, read from the model
    /// ([`Hand::fingers`], [`Hand::palm`]). With `opposed = false`, any `min_fingers` of
    /// the four fingers, the thumb included (a push or a press). Output `fingers`: the
    /// fingers touching, the thumb included.
    Grasp {
        /// Whose hand.
        hand: Hand,
        /// The object's geoms.
        object: GeomSet,
        /// Fingers that must touch (1 to 3 opposed, 1 to 4 not).
        #[serde(default = "one_finger")]
        min_fingers: u32,
        /// Whether the thumb or the palm must oppose them (a grasp).
        #[serde(default = "yes")]
        opposed: bool,
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
    /// holds. Outputs `illegal`, `on_goal` (disks seated on the goal post in goal order).
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
            Self::HanoiTowers { .. } => &["illegal", "on_goal"],
            Self::Grasp { .. } => &["fingers"],
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
            Self::Contact { .. } | Self::Grasp { .. } => ConstraintKind::Contact,
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

/// The default fingers of a grasp: one, opposed by the thumb or the palm.
fn one_finger() -> u32 {
    1
}

fn yes() -> bool {
    true
}
