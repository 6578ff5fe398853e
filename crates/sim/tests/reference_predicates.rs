//! Our task specs' conditions against the DexJoCo reference environments' own, state by
//! state: `tests/python/reference_predicates.py` samples a few hundred MuJoCo states near
//! each threshold of every task's conditions on the reference scenes and records the
//! reference code's answers; here each task's [`TaskEnv`] is built from the reference
//! env's `state[0]` (the reset-time values come from our own restore, whose FULLPHYSICS
//! state must equal the reference's after reset), every sampled state is set into our
//! data (`mj_setState`, then `mj_forward`) and our nodes are evaluated on it: a clone of
//! the checker as reset, one substep sample and one `after_step` (the per-step value,
//! before any hold counter reaches its target; the Hanoi state is held for its illegal
//! steps). No entry point beyond the checker's public API is needed.
//!
//! Where a sample names a prior, a priming state is applied first: a whole step (sets a
//! `joint_hysteresis` latch) or one substep sample (the hammer's speed window).

mod common;

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

use dexjoco_core::NameKind;
use dexjoco_sim::mujoco_rs::prelude::{MjtDisableBit, MjtState};
use dexjoco_sim::{EnvOptions, SuccessChecker, TaskEnv, name_id};

const FULL: u32 = MjtState::mjSTATE_FULLPHYSICS as u32;
const SAMPLES: &str = "300";

/// One task's sampled states and the reference answers.
struct Samples {
    width: usize,
    size: usize,
    count: usize,
    disableflags: i32,
    /// Per node (or `node.output`): the reference's answer per sample (booleans as 0 / 1).
    nodes: BTreeMap<String, Vec<f64>>,
    prior: Vec<bool>,
    /// How a priming state is applied: `step` (a whole step: latches) or `substep`
    /// (one speed sample: the nail).
    prime_with: Option<String>,
    /// Steps each sample is held for (the Hanoi illegal verdict's steps; else 1).
    steps: usize,
    blob: Vec<f64>,
}

impl Samples {
    fn read(dir: &Path, task: &str, meta: &serde_json::Value) -> Self {
        let bytes = fs_err::read(dir.join(format!("{task}.f64"))).unwrap();
        let blob = bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
            .collect();
        let n = |k: &str| usize::try_from(meta[k].as_u64().unwrap()).unwrap();
        Self {
            width: n("width"),
            size: n("state_size"),
            count: n("samples"),
            disableflags: i32::try_from(meta["disableflags"].as_i64().unwrap()).unwrap(),
            nodes: meta["nodes"]
                .as_object()
                .unwrap()
                .iter()
                .map(|(k, v)| {
                    let values = v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap());
                    (k.clone(), values.collect())
                })
                .collect(),
            prior: meta["prior"]
                .as_array()
                .unwrap()
                .iter()
                .map(|b| b.as_bool().unwrap())
                .collect(),
            prime_with: meta["prime_with"].as_str().map(str::to_owned),
            steps: n("steps"),
            blob,
        }
    }

    fn state0(&self) -> &[f64] {
        &self.blob[..self.width]
    }

    /// 0: the reset state, then per sample its priming state and itself.
    fn physics(&self, k: usize) -> &[f64] {
        let start = self.width + k * self.size;
        &self.blob[start..start + self.size]
    }
}

/// Free joints whose reset pose the reference draws at random and its state vector does
/// not record, so that no restore can reproduce them; no condition reads them.
/// click_mouse: the monitor's xy (`panda_click_mouse_env.py` reset, `_PLANT_XY_BOUNDS`).
const NOT_IN_STATE0: &[(&str, &str)] = &[("click_mouse", "display_root")];

/// Our reset state against the reference's: the largest difference of the FULLPHYSICS
/// state (time and the free joints of [`NOT_IN_STATE0`] aside), or infinity when the
/// sizes differ.
fn reset_difference(task: &str, env: &TaskEnv, reference: &[f64]) -> f64 {
    let data = env.data();
    let ours = data.state(FULL);
    if ours.len() != reference.len() {
        eprintln!(
            "{task}: state sizes: ours {}, reference {}",
            ours.len(),
            reference.len()
        );
        return f64::INFINITY;
    }
    let mut skip = vec![0];
    for (_, joint) in NOT_IN_STATE0.iter().filter(|(t, _)| *t == task) {
        let j = name_id(data.model(), NameKind::Joint, joint).expect("joint");
        let adr = usize::try_from(data.model().jnt_qposadr()[j]).unwrap();
        skip.extend(1 + adr..1 + adr + 7);
    }
    let (at, d) = ours
        .iter()
        .zip(reference)
        .enumerate()
        .filter(|(i, _)| !skip.contains(i))
        .map(|(i, (a, b))| (i, (a - b).abs()))
        .fold((0, 0.0), |m, x| if x.1 > m.1 { x } else { m });
    if d > 0.0 {
        eprintln!(
            "{task}: reset: largest difference at state index {at}: ours {}, reference {}",
            ours[at], reference[at]
        );
    }
    d
}

/// Sets a FULLPHYSICS state and runs `mj_forward`.
fn load(env: &mut TaskEnv, state: &[f64]) {
    let data = env.data_mut();
    data.set_state(state, FULL).unwrap();
    data.forward();
}

/// A node's value (0 / 1) or, for `node.output`, its output.
fn read(checker: &SuccessChecker, key: &str) -> Option<f64> {
    match key.split_once('.') {
        Some((node, output)) => checker.output(node, output),
        None => checker.value(key).map(|v| f64::from(u8::from(v))),
    }
}

/// Compares one task; returns its summary line and any disagreements.
fn compare_task(task: &str, s: &Samples) -> (String, Vec<String>) {
    let spec = common::spec(task);
    let scene = common::scene(task);
    let options = EnvOptions {
        disable_multiccd: s.disableflags & MjtDisableBit::mjDSBL_MULTICCD as i32 != 0,
    };
    let mut env = TaskEnv::from_initial_state(&scene, &spec, s.state0(), options).unwrap();
    let mut bad = Vec::new();
    let flags = env.data().model_opt().disableflags;
    if flags != s.disableflags {
        bad.push(format!(
            "{task}: disable flags {flags} vs {}",
            s.disableflags
        ));
    }
    let reset = reset_difference(task, &env, s.physics(0));
    if reset > 1e-9 {
        bad.push(format!("{task}: reset states differ by {reset:.3e}"));
    }
    let base: SuccessChecker = env.checker().clone();
    let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
    for i in 0..s.count {
        let mut checker = base.clone();
        if s.prior[i] {
            load(&mut env, s.physics(1 + 2 * i));
            checker.after_substep(env.data());
            if s.prime_with.as_deref() == Some("step") {
                checker.after_step(env.data_mut());
            }
        }
        load(&mut env, s.physics(2 + 2 * i));
        for _ in 0..s.steps {
            checker.after_substep(env.data());
            checker.after_step(env.data_mut());
        }
        for (node, answers) in &s.nodes {
            let ours = read(&checker, node).unwrap_or_else(|| panic!("{task}: no node '{node}'"));
            *counts.entry(node).or_default() += usize::from(answers[i] != 0.0);
            if (ours - answers[i]).abs() > 1e-12 {
                bad.push(format!(
                    "{task}: sample {i} (prior {}): '{node}' ours {ours}, reference {}",
                    s.prior[i], answers[i]
                ));
            }
        }
    }
    for (node, t) in &counts {
        if *t == 0 || *t == s.count {
            bad.push(format!(
                "{task}: '{node}' is {t}/{} true: not both answers",
                s.count
            ));
        }
    }
    let nodes: Vec<String> = counts
        .iter()
        .map(|(n, t)| format!("{n} {t}/{}", s.count - t))
        .collect();
    let line = format!(
        "{task}: {} samples, reset diff {reset:.1e}; true/false: {}; {} disagreements",
        s.count,
        nodes.join(", "),
        bad.len()
    );
    (line, bad)
}

#[test]
fn our_conditions_answer_as_the_reference_on_sampled_states() {
    let t = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    dexjoco_testkit::run_reference_python(
        "reference_predicates.py",
        &["--out", out, "--samples", SAMPLES],
    );
    eprintln!("reference side: {:.1} s", t.elapsed().as_secs_f64());
    let manifest: serde_json::Value =
        serde_json::from_str(&fs_err::read_to_string(dir.path().join("manifest.json")).unwrap())
            .unwrap();
    let tasks: Vec<&String> = manifest.as_object().unwrap().keys().collect();
    let mut ids: Vec<String> = common::specs().into_iter().map(|s| s.id).collect();
    ids.sort();
    let mut sampled: Vec<String> = tasks.iter().map(|t| (*t).clone()).collect();
    sampled.sort();
    assert_eq!(sampled, ids, "every task is sampled");
    let mut bad = Vec::new();
    for (task, meta) in manifest.as_object().unwrap() {
        let (line, mut b) = compare_task(task, &Samples::read(dir.path(), task, meta));
        eprintln!("{line}");
        bad.append(&mut b);
    }
    eprintln!("total: {:.1} s", t.elapsed().as_secs_f64());
    assert!(
        bad.is_empty(),
        "{} disagreements:\n{}",
        bad.len(),
        bad.iter().take(40).cloned().collect::<Vec<_>>().join("\n")
    );
}
