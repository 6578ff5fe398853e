//! The built-in scenes: every task of `schemas/tasks/` loads as a built-in scene,
//! resolves its spec's names, renders and holds still over its step cap with the arm at
//! home; the OSC tracks a target on a built-in scene; scripted demonstrations made on
//! the built-in scenes replay to success.

#[path = "../../sim/tests/common/mod.rs"]
mod common;

use dexjoco_core::{FrameArray, HAND_DOF, TaskSpec};
use dexjoco_render::{CameraView, RenderQuality, RenderSettings, Renderer};
use dexjoco_scripted as scripted;
use dexjoco_sim::mujoco_rs::prelude::MjData;
use dexjoco_sim::{
    EnvOptions, Feedback, SceneSource, TaskEnv, builtin, load_task_scene, orientation_error,
    unresolved_names,
};

/// A deterministic U(0, 1) sequence (xorshift64*).
fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    move || {
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        (x.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn builtin_scene(spec: &TaskSpec) -> dexjoco_sim::Scene {
    load_task_scene(&SceneSource::BuiltIn, spec).expect("built-in scene loads")
}

/// Hand targets at the reset pose (the spec's, else straight fingers, thumb at home).
fn home_hand(spec: &TaskSpec) -> [f64; HAND_DOF] {
    let mut h = [0.0; HAND_DOF];
    match &spec.reset.hand_qpos {
        Some(v) => h.copy_from_slice(v),
        None => h[12] = 0.263,
    }
    h
}

/// An action that keeps every arm's current target and the reset hand pose.
fn hold_action(env: &TaskEnv) -> Vec<f64> {
    let hand = home_hand(env.spec());
    let mut a = Vec::new();
    for (p, q) in env.targets() {
        a.extend_from_slice(&p);
        a.extend_from_slice(&q);
        a.extend_from_slice(&hand);
    }
    a
}

/// Loads, resolves, renders and holds one task; returns what went wrong.
fn check_task(spec: &TaskSpec, renderer: &mut Option<Renderer>) -> Result<(), String> {
    let scene = load_task_scene(&SceneSource::BuiltIn, spec).map_err(|e| e.to_string())?;
    let missing = unresolved_names(spec, &scene.model);
    if !missing.is_empty() {
        return Err(format!("unresolved names {missing:?}"));
    }
    // Renders: the first spec camera sees something other than the background.
    let cam = scene
        .camera_id(&spec.cameras[0].camera)
        .map_err(|e| e.to_string())?;
    let mut data = MjData::new(scene.model.clone());
    data.forward();
    let r = renderer.get_or_insert_with(|| {
        Renderer::new(
            &scene.model,
            RenderSettings {
                width: 96,
                height: 72,
                quality: RenderQuality::FAST,
                depth: false,
                geometry: dexjoco_render::Geometry::Full,
            },
        )
        .expect("renderer")
    });
    let mut r2 = Renderer::new(&scene.model, r.settings()).map_err(|e| e.to_string())?;
    let f = r2
        .render(&mut data, CameraView::Fixed(cam))
        .map_err(|e| e.to_string())?;
    let first = f.pixel(0, 0);
    let varied = (0..f.height)
        .flat_map(|y| (0..f.width).map(move |x| (x, y)))
        .filter(|&(x, y)| f.pixel(x, y) != first)
        .count();
    if varied < (f.width * f.height / 10) as usize {
        return Err(format!(
            "camera '{}' renders a blank image",
            spec.cameras[0].camera
        ));
    }

    // Holds still over the step cap with the arm at home.
    let mut env = TaskEnv::new(&scene, spec, EnvOptions::default()).map_err(|e| e.to_string())?;
    let tcp0: Vec<[f64; 3]> = env.targets().iter().map(|t| t.0).collect();
    let hold = hold_action(&env);
    let settle = 100.min(spec.step_cap);
    let mut qpos_settled = Vec::new();
    for k in 0..spec.step_cap {
        env.step(&hold).map_err(|e| e.to_string())?;
        if k + 1 == settle {
            qpos_settled = env.data().qpos().to_vec();
        }
    }
    let d = env.data();
    let vmax = d.qvel().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if !vmax.is_finite() || vmax > 0.05 {
        return Err(format!("max |qvel| {vmax} after {} steps", spec.step_cap));
    }
    let drift = d
        .qpos()
        .iter()
        .zip(&qpos_settled)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    if drift > 0.01 {
        return Err(format!("qpos drifted {drift} after settling"));
    }
    for (arm, p0) in env.robot().arms.iter().zip(&tcp0) {
        let p = env.robot().tcp_pose(d, arm).0;
        let e = (0..3).map(|i| (p[i] - p0[i]).powi(2)).sum::<f64>().sqrt();
        if e > 0.005 {
            return Err(format!("arm '{}' left home by {e} m", arm.name));
        }
    }
    Ok(())
}

#[test]
fn every_task_loads_renders_and_holds_still_as_a_built_in_scene() {
    let mut renderer = None;
    let mut without_fragment = Vec::new();
    let mut failures = Vec::new();
    for spec in common::specs() {
        if builtin::object_fragment(&spec.id).is_none() {
            without_fragment.push(spec.id.clone());
            continue;
        }
        if let Err(e) = check_task(&spec, &mut renderer) {
            failures.push(format!("{}: {e}", spec.id));
        }
    }
    assert!(
        failures.is_empty(),
        "built-in scenes failing: {failures:#?}"
    );
    assert!(
        without_fragment.is_empty(),
        "tasks without a built-in scene (no crates/sim/assets/builtin/objects/<id>.xml): {}",
        without_fragment.join(", ")
    );
}

#[test]
fn a_missing_fragment_is_a_clear_error() {
    let mut spec = common::spec("click_mouse");
    spec.id = "no_such_task".into();
    let e = load_task_scene(&SceneSource::BuiltIn, &spec)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("no_such_task") && e.contains("--scene-dir"),
        "{e}"
    );
}

#[test]
fn the_osc_tracks_a_pose_target_on_the_built_in_scene() {
    let spec = common::spec("click_mouse");
    let scene = builtin_scene(&spec);
    let mut env = TaskEnv::new(&scene, &spec, EnvOptions::default()).unwrap();
    let (p0, q0) = env.targets()[0];
    // 0.1 m forward and down, and 15 degrees about world z.
    let p = [p0[0] + 0.1, p0[1] - 0.05, p0[2] - 0.05];
    let (s, c) = (7.5f64.to_radians().sin(), 7.5f64.to_radians().cos());
    let q = [
        c * q0[0] - s * q0[3],
        c * q0[1] - s * q0[2],
        c * q0[2] + s * q0[1],
        c * q0[3] + s * q0[0],
    ];
    let mut a = hold_action(&env);
    a[..3].copy_from_slice(&p);
    a[3..7].copy_from_slice(&q);
    for _ in 0..250 {
        env.step(&a).unwrap();
    }
    let arm = &env.robot().arms[0];
    let (x, _) = env.robot().tcp_pose(env.data(), arm);
    let e_pos = (0..3).map(|i| (x[i] - p[i]).powi(2)).sum::<f64>().sqrt();
    let e_rot = orientation_error(&env.data().site_xmat()[arm.site], &q);
    let e_deg = e_rot.iter().map(|v| v * v).sum::<f64>().sqrt().to_degrees();
    assert!(e_pos < 0.005, "position error {e_pos} m");
    assert!(e_deg < 2.0, "orientation error {e_deg} deg");
}

/// Replays a demo; returns whether it succeeded on its last step, the number of active
/// feedback rules before and after, and how many RGB values the feedback changes in a
/// rendering of `camera` at the end.
fn replays(
    scene: &dexjoco_sim::Scene,
    spec: &TaskSpec,
    ep: &dexjoco_core::Episode,
    camera: &str,
) -> (bool, usize, usize, usize) {
    let states: &FrameArray = ep.array(dexjoco_core::Episode::STATE).unwrap();
    let actions = ep.array(dexjoco_core::Episode::ACTION).unwrap();
    let mut env =
        TaskEnv::from_initial_state(scene, spec, states.row(0), EnvOptions::default()).unwrap();
    let feedback = Feedback::new(spec, &scene.model).unwrap();
    let before = feedback.active(env.checker()).len();
    let r = env.rollout(actions).unwrap();
    let after = feedback.active(env.checker()).len();
    let settings = RenderSettings {
        width: 128,
        height: 96,
        quality: RenderQuality::FAST,
        depth: false,
        geometry: dexjoco_render::Geometry::Full,
    };
    let mut renderer = Renderer::new(&scene.model, settings).unwrap();
    let view = CameraView::Fixed(scene.camera_id(camera).unwrap());
    let plain = renderer.render(env.data_mut(), view).unwrap();
    renderer.update_scene(env.data_mut(), view);
    feedback.apply(env.checker(), renderer.scene_mut());
    let lit = renderer.draw().unwrap();
    let changed = plain
        .rgb
        .iter()
        .zip(&lit.rgb)
        .filter(|(a, b)| a != b)
        .count();
    (
        r.first_failure().is_none() && r.first_success() == Some(ep.len() - 1),
        before,
        after,
        changed,
    )
}

#[test]
fn scripted_click_mouse_succeeds_on_the_built_in_scene() {
    let spec = common::spec("click_mouse");
    let scene = builtin_scene(&spec);
    for seed in [3, 11] {
        let s0 = TaskEnv::sample_initial_state(&scene, &spec, &mut uniform(seed)).unwrap();
        let ep = scripted::click_mouse_demo(&scene, &spec, &s0, "builtin_click").unwrap();
        assert!(
            ep.len() < spec.step_cap,
            "seed {seed}: no success in {} steps",
            ep.len()
        );
        let (ok, before, after, changed) = replays(&scene, &spec, &ep, "left");
        assert!(ok, "seed {seed}: replay does not succeed");
        assert_eq!(
            (before, after),
            (0, 1),
            "the monitor turns blue on the click"
        );
        assert!(
            changed > 30,
            "the blue screen shows ({changed} values changed)"
        );
    }
}

#[test]
fn scripted_unlock_ipad_succeeds_on_the_built_in_scene() {
    let spec = common::spec("bimanual_unlock_ipad");
    let scene = builtin_scene(&spec);
    for seed in [5, 13] {
        let s0 = TaskEnv::sample_initial_state(&scene, &spec, &mut uniform(seed)).unwrap();
        let ep = scripted::unlock_ipad_demo(&scene, &spec, &s0, "builtin_ipad").unwrap();
        assert!(
            ep.len() < spec.step_cap,
            "seed {seed}: no success in {} steps",
            ep.len()
        );
        let (ok, before, after, changed) = replays(&scene, &spec, &ep, "back");
        assert!(ok, "seed {seed}: replay does not succeed");
        assert_eq!(
            (before, after),
            (0, 4),
            "three digits lit and the screen unlocked"
        );
        assert!(
            changed > 30,
            "the lit keypad shows ({changed} values changed)"
        );
    }
}

#[test]
fn feedback_rules_resolve_and_bad_rules_are_clear_errors() {
    let spec = common::spec("click_mouse");
    let scene = builtin_scene(&spec);
    assert_eq!(Feedback::new(&spec, &scene.model).unwrap().len(), 1);
    // The click_mouse rule names a node the iPad task lacks: the error names the rule.
    let e = Feedback::new(&common::spec("bimanual_unlock_ipad"), &scene.model).unwrap_err();
    assert!(e.to_string().contains("feedback_display_blue"), "{e}");
}
