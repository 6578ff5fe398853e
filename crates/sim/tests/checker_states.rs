//! The success checker on constructed states of a small scene: each g_pose, g_joint,
//! g_contact and g_seq primitive satisfied and violated, held N-1 vs N steps, edges,
//! counters and early failure, read from real MuJoCo data.

use std::sync::Arc;

use dexjoco_core::TaskSpec;
use dexjoco_sim::mujoco_rs::prelude::{MjData, MjModel};
use dexjoco_sim::{Scene, SuccessChecker, Verdict};

const XML: &str = r#"
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="pad" pos="0.5 0 0">
      <geom name="pad_geom" type="cylinder" size="0.15 0.001" contype="0" conaffinity="0"/>
      <site name="pad_top" pos="0 0 0.01"/>
    </body>
    <body name="box" pos="0 0 0.5">
      <freejoint name="box_root"/>
      <geom name="box_geom" type="box" size="0.05 0.05 0.05"/>
      <site name="box_corner" pos="0.05 0 0"/>
      <body name="lid" pos="0 0 0.05">
        <joint name="hinge" type="hinge" axis="0 1 0" range="-1 1"/>
        <geom name="lid_geom" type="box" size="0.05 0.05 0.005" pos="0 0 0.01"/>
      </body>
    </body>
  </worldbody>
  <sensor>
    <framepos name="box_pos" objtype="body" objname="box"/>
    <jointpos name="hinge_pos" joint="hinge"/>
  </sensor>
</mujoco>"#;

const SPEC: &str = r#"
id = "constructed"
name = "Constructed"
setup = "single_arm"
scene = "inline"
prompt = "test"
step_cap = 100
success = "done"
failure = "fail"
cameras = [{ key = "front", camera = "front" }]

[state]
width = 24
objects = []

[nodes.on_pad]
kind = "point_in_cylinder"
point = { sensor = "box_pos" }
center = { body = "pad" }
radius = 0.15
along = [-0.05, 0.2]

[nodes.in_box]
kind = "point_in_box"
point = { site = "box_corner" }
origin = { body = "box" }
axes = "origin"
min = [0.04, -0.01, -0.01]
max = [0.06, 0.01, 0.01]

[nodes.upright]
kind = "axis_alignment"
frame = { body = "box" }
axis = "z"
target = [0.0, 0.0, 1.0]
max_angle_deg = 10.0

[nodes.raised]
kind = "height_above_reset"
sites = ["box_corner"]
min_rise = 0.1

[nodes.armed]
kind = "joint_hysteresis"
joint = { sensor = "hinge_pos" }
clear = { op = "le", value = -0.5 }
set = { op = "ge", value = 0.5 }

[nodes.closed_after_open]
kind = "falling_edge"
of = "armed"

[nodes.pinches]
kind = "counter"
of = "closed_after_open"
at_least = 2

[nodes.touch_floor]
kind = "contact"
a = { geoms = ["box_geom"] }
b = { geoms = ["floor"] }

[nodes.touch_any]
kind = "contact"
a = { geoms = ["box_geom"] }
b = "any"

[nodes.touch_foreign]
kind = "contact"
a = { geoms = ["lid_geom"] }
b = { outside_subtree = "box" }

[nodes.on_pad_open]
kind = "joint_threshold"
joint = { qpos = "hinge" }
op = "gt"
value = 0.2

[nodes.ready]
kind = "all"
of = ["on_pad", "pinches"]

[nodes.done]
kind = "held"
of = "ready"
steps = 3

[nodes.off_pad]
kind = "not"
of = "on_pad"

[nodes.fail]
kind = "all"
of = ["off_pad", "on_pad_open"]
"#;

struct Rig {
    data: MjData<Arc<MjModel>>,
    checker: SuccessChecker,
}

impl Rig {
    fn new() -> Self {
        let spec = TaskSpec::from_toml_str(SPEC, "constructed").unwrap();
        let scene = Scene::from_xml_str(XML, "constructed").unwrap();
        let mut data = MjData::new(scene.model.clone());
        data.forward();
        let mut checker = SuccessChecker::new(&spec, &scene.model).unwrap();
        checker.reset(&data);
        Self { data, checker }
    }

    /// Places the box (xyz, quat) and the hinge, computes the kinematics, evaluates.
    fn set(&mut self, pos: [f64; 3], quat: [f64; 4], hinge: f64) -> Verdict {
        let q = self.data.qpos_mut();
        q[..3].copy_from_slice(&pos);
        q[3..7].copy_from_slice(&quat);
        q[7] = hinge;
        self.data.forward();
        self.checker.after_step(&mut self.data)
    }

    fn value(&self, node: &str) -> bool {
        self.checker.value(node).unwrap()
    }
}

const UP: [f64; 4] = [1.0, 0.0, 0.0, 0.0];

#[test]
fn pose_primitives_satisfied_and_violated() {
    let mut r = Rig::new();
    r.set([0.5, 0.1, 0.05], UP, 0.0);
    assert!(r.value("on_pad") && r.value("in_box") && r.value("upright"));
    assert!(!r.value("raised"), "reset height was 0.5");
    r.set([0.5, 0.16, 0.05], UP, 0.0);
    assert!(!r.value("on_pad"), "0.16 from the pad centre");
    r.set([0.5, 0.0, 0.3], UP, 0.0);
    assert!(!r.value("on_pad"), "above the cylinder");
    r.set([0.0, 0.0, 0.65], UP, 0.0);
    assert!(r.value("raised"));
    // Tilted 20 degrees about x: not upright; the corner site stays in the box frame.
    let h = 10f64.to_radians();
    r.set([0.0, 0.0, 0.5], [h.cos(), h.sin(), 0.0, 0.0], 0.0);
    assert!(!r.value("upright") && r.value("in_box"));
}

#[test]
fn contacts_pairs_any_and_outside_subtree() {
    let mut r = Rig::new();
    r.set([0.0, 0.0, 0.5], UP, 0.0);
    assert!(!r.value("touch_floor") && !r.value("touch_any"));
    r.set([0.0, 0.0, 0.049], UP, 0.0);
    assert!(r.value("touch_floor") && r.value("touch_any"));
    assert!(!r.value("touch_foreign"));
    // Upside down: the lid touches the floor, which is outside the box's subtree.
    r.set([0.0, 0.0, 0.058], [0.0, 1.0, 0.0, 0.0], 0.0);
    assert!(r.value("touch_foreign"), "lid on the floor");
}

#[test]
fn held_n_minus_one_versus_n_with_counted_pinches() {
    let mut r = Rig::new();
    let on = [0.5, 0.0, 0.05];
    // Two pinches: open (>= 0.5) then close (<= -0.5), twice, off the pad.
    for h in [0.6, -0.6, 0.0, 0.7, -0.55] {
        let v = r.set([0.0, 0.0, 0.5], UP, h);
        assert!(!v.success);
    }
    assert_eq!(r.checker.output("pinches", "count"), Some(2.0));
    // On the pad: 2 steps (N-1) are not enough, the 3rd is.
    assert!(!r.set(on, UP, -0.55).success);
    assert!(!r.set(on, UP, -0.55).success);
    assert_eq!(r.checker.output("done", "count"), Some(2.0));
    assert!(r.set(on, UP, -0.55).success);
    // A step off the pad resets the hold.
    assert!(!r.set([0.0, 0.0, 0.5], UP, 0.0).success);
    assert!(!r.set(on, UP, 0.0).success);
}

#[test]
fn hysteresis_band_and_early_failure() {
    let mut r = Rig::new();
    r.set([0.0, 0.0, 0.5], UP, 0.4);
    assert!(!r.value("armed"), "0.4 is inside the band");
    r.set([0.0, 0.0, 0.5], UP, 0.5);
    assert!(r.value("armed"));
    r.set([0.0, 0.0, 0.5], UP, -0.4);
    assert!(r.value("armed") && !r.value("closed_after_open"));
    r.set([0.0, 0.0, 0.5], UP, -0.5);
    assert!(
        !r.value("armed") && r.value("closed_after_open"),
        "falling edge"
    );
    r.set([0.0, 0.0, 0.5], UP, -0.5);
    assert!(!r.value("closed_after_open"), "an edge lasts one step");
    // Failure: the lid open (qpos, current) while off the pad.
    let v = r.set([0.5, 0.0, 0.05], UP, 0.3);
    assert!(!v.failure, "on the pad");
    let v = r.set([0.0, 0.0, 0.5], UP, 0.3);
    assert!(v.failure && !v.success);
    // A reset clears counters and latches.
    r.checker.reset(&r.data);
    assert_eq!(r.checker.output("pinches", "count"), Some(0.0));
}
