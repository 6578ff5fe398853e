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

const MECHANICS_XML: &str = r#"
<mujoco>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="nail" mocap="true" pos="0 0 0.05">
      <geom name="nail_head" type="cylinder" size="0.01 0.05" contype="1" conaffinity="1"/>
    </body>
    <body name="hammer" pos="0 0 0.5">
      <freejoint name="hammer_root"/>
      <geom name="face" type="box" size="0.02 0.02 0.02"/>
    </body>
    <body name="keys" pos="1 0 0.5">
      <freejoint name="keys_root"/>
      <geom name="btn1_cyl" type="box" size="0.01 0.01 0.01" pos="0 0 0"/>
      <geom name="btn2_cyl" type="box" size="0.01 0.01 0.01" pos="0.1 0 0"/>
    </body>
    <body name="finger" mocap="true" pos="1 0 0.8">
      <geom name="tip" type="sphere" size="0.01"/>
    </body>
  </worldbody>
</mujoco>"#;

const MECHANICS_SPEC: &str = r#"
id = "mechanics"
name = "Mechanics"
setup = "single_arm"
scene = "inline"
prompt = "test"
step_cap = 100
success = "driven"
failure = "keypad.failed"
cameras = [{ key = "front", camera = "front" }]

[state]
width = 24
objects = []

[nodes.nail]
kind = "nail_sinking"
hammer = ["face"]
nail = ["nail_head"]
face = "face"
nail_body = "nail"
window = 12
vz_divisor = 0.02
min_vz = -0.02
gain = 0.008
max_scale = 3.0
max_depth = 0.0726

[nodes.driven]
kind = "value_threshold"
of = "nail.depth"
op = "ge"
value = 0.04

[nodes.keypad]
kind = "keypad"
fingers = ["tip"]
password = [1, 2]
buttons = [{ digit = 2, geom = "btn2_cyl" }, { digit = 1, geom = "btn1_cyl" }]
"#;

/// Places the fingertip on a button x (or away) and evaluates: (unlocked, failed).
fn press(
    data: &mut MjData<Arc<MjModel>>,
    checker: &mut SuccessChecker,
    x: Option<f64>,
) -> (bool, f64) {
    data.mocap_pos_mut()[1] = match x {
        Some(x) => [x, 0.0, 0.515],
        None => [1.0, 0.0, 0.8],
    };
    data.forward();
    checker.after_step(data);
    (
        checker.value("keypad").unwrap(),
        checker.output("keypad", "failed").unwrap(),
    )
}

/// A control step of 10 physics substeps with the checker's bookkeeping.
fn control_step(data: &mut MjData<Arc<MjModel>>, checker: &mut SuccessChecker) -> Verdict {
    for _ in 0..10 {
        data.step();
        checker.after_substep(data);
    }
    checker.after_step(data)
}

#[test]
fn a_falling_hammer_sinks_the_nail_mocap() {
    let spec = TaskSpec::from_toml_str(MECHANICS_SPEC, "mechanics").unwrap();
    let scene = Scene::from_xml_str(MECHANICS_XML, "mechanics").unwrap();
    let mut data = MjData::new(scene.model.clone());
    data.forward();
    let mut checker = SuccessChecker::new(&spec, &scene.model).unwrap();
    assert_eq!(
        checker.node_names()[0],
        "keypad",
        "mechanics are evaluated first"
    );
    checker.reset(&data);
    let mut driven_at = None;
    for step in 0..40 {
        let v = control_step(&mut data, &mut checker);
        if v.success && driven_at.is_none() {
            driven_at = Some(step);
        }
    }
    let depth = checker.output("nail", "depth").unwrap();
    // The hammer hits at ~3 m/s (vz reads 1/10 of it: scale 3, +0.024 per step in
    // contact) and keeps scoring while the fast samples stay in the window.
    assert!(depth >= 0.04, "depth {depth}");
    assert!(driven_at.is_some());
    assert!(
        (data.mocap_pos()[0][2] - (0.05 - depth)).abs() < 1e-12,
        "the nail moved down"
    );
}

#[test]
fn fingertip_presses_enter_digits_in_geom_order() {
    let spec = TaskSpec::from_toml_str(MECHANICS_SPEC, "mechanics").unwrap();
    let scene = Scene::from_xml_str(MECHANICS_XML, "mechanics").unwrap();
    let mut data = MjData::new(scene.model.clone());
    data.forward();
    let mut checker = SuccessChecker::new(&spec, &scene.model).unwrap();
    checker.reset(&data);
    assert_eq!(
        press(&mut data, &mut checker, Some(1.0)),
        (false, 0.0),
        "digit 1"
    );
    assert_eq!(
        press(&mut data, &mut checker, Some(1.0)),
        (false, 0.0),
        "still the same press"
    );
    assert_eq!(press(&mut data, &mut checker, None), (false, 0.0));
    assert_eq!(
        press(&mut data, &mut checker, Some(1.1)),
        (true, 0.0),
        "digit 2 unlocks"
    );
    // A new keypad: pressing 2 first is a wrong digit (the failure of the episode).
    checker.reset(&data);
    assert_eq!(press(&mut data, &mut checker, None), (false, 0.0));
    assert_eq!(press(&mut data, &mut checker, Some(1.1)), (false, 1.0));
}
