//! A scripted click_mouse demonstration on the reference scene: its replay succeeds,
//! twice with identical states equal to the recording, and a perturbed action fails;
//! a scripted bimanual_unlock_ipad demonstration replays to success.

#[path = "../../sim/tests/common/mod.rs"]
mod common;

use dexjoco_core::{Episode, FrameArray};
use dexjoco_scripted as scripted;
use dexjoco_sim::{EnvOptions, TaskEnv};

/// A deterministic U(0, 1) sequence (xorshift64*).
fn uniform(seed: u64) -> impl FnMut() -> f64 {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut next = move || {
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        (x.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    };
    for _ in 0..8 {
        next();
    }
    next
}

fn bits(a: &FrameArray) -> Vec<u64> {
    a.as_slice().iter().map(|v| v.to_bits()).collect()
}

#[test]
fn scripted_click_mouse_replays_and_a_perturbed_action_fails() {
    let spec = common::spec("click_mouse");
    let scene = common::scene("click_mouse");
    let s0 = TaskEnv::sample_initial_state(&scene, &spec, &mut uniform(7)).unwrap();
    let ep = scripted::click_mouse_demo(&scene, &spec, &s0, "click_mouse_scripted_0").unwrap();
    ep.check_consistent().unwrap();
    ep.check_width(Episode::ACTION, 23).unwrap();
    ep.check_width(Episode::ACTION_ROTVEC, 22).unwrap();
    ep.check_width(Episode::STATE, 31).unwrap();
    let actions = ep.array(Episode::ACTION).unwrap();
    let recorded = ep.array(Episode::STATE).unwrap();
    assert_eq!(
        &recorded.row(0)[23..],
        &s0[23..],
        "the privileged part is the initial state"
    );
    eprintln!("scripted click_mouse: {} steps", ep.len());

    // Replay from state[0], twice: success on the last recorded step, identical states,
    // equal to the recording.
    let replay = || {
        let mut env =
            TaskEnv::from_initial_state(&scene, &spec, recorded.row(0), EnvOptions::default())
                .unwrap();
        env.rollout(actions).unwrap()
    };
    let first = replay();
    assert_eq!(first.first_success(), Some(ep.len() - 1));
    assert_eq!(first.first_failure(), None);
    assert_eq!(bits(&first.states), bits(recorded), "replay = recording");
    let second = replay();
    assert_eq!(bits(&second.states), bits(&first.states));
    assert_eq!(second.verdicts, first.verdicts);

    // One action perturbed just before the click: the arm jerks up and the recorded
    // actions no longer reach success.
    let mut perturbed = actions.clone();
    let k = ep.len() - 15;
    perturbed.row_mut(k)[2] += 0.5;
    let mut env =
        TaskEnv::from_initial_state(&scene, &spec, recorded.row(0), EnvOptions::default()).unwrap();
    let r = env.rollout(&perturbed).unwrap();
    assert!(
        !r.succeeded(),
        "a perturbed demo still succeeded at {:?}",
        r.first_success()
    );
}

#[test]
fn scripted_unlock_ipad_replays_to_success() {
    let spec = common::spec("bimanual_unlock_ipad");
    let scene = common::scene("bimanual_unlock_ipad");
    let s0 = TaskEnv::sample_initial_state(&scene, &spec, &mut uniform(3)).unwrap();
    let ep = scripted::unlock_ipad_demo(&scene, &spec, &s0, "unlock_ipad_scripted_0").unwrap();
    ep.check_width(Episode::ACTION, 46).unwrap();
    ep.check_width(Episode::STATE, 61).unwrap();
    eprintln!("scripted bimanual_unlock_ipad: {} steps", ep.len());
    let recorded = ep.array(Episode::STATE).unwrap();
    let mut env =
        TaskEnv::from_initial_state(&scene, &spec, recorded.row(0), EnvOptions::default()).unwrap();
    let r = env.rollout(ep.array(Episode::ACTION).unwrap()).unwrap();
    assert_eq!(r.first_success(), Some(ep.len() - 1));
    assert_eq!(r.first_failure(), None);
    assert_eq!(bits(&r.states), bits(recorded), "replay = recording");
    assert_eq!(env.checker().output("keypad", "index"), Some(3.0));
}
