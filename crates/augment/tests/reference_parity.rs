//! Simulation parity with the DexJoCo reference code itself: the same episodes replayed by
//! the reference replay script (`scripts/replay_demos_zarr.py`, its environments run
//! headless under MuJoCo 3.17.0 by `tests/python/dexjoco_reference.py`) and by our
//! `TaskEnv`, on the reference scenes, for all 11 tasks: a demonstration planned by
//! `scripted` from one seeded reset, and the deliberately wrong plans. Each demonstration
//! that succeeds is also replayed through `augment` (issue #26).
//!
//! The reference's arithmetic depends on the CPU (numpy's SIMD loops, OpenBLAS's
//! kernels) and contact turns last bits into other success steps, so the harness pins it
//! (`tests/python/reference_arithmetic.py`; `$DEXJOCO_REFERENCE_ARITHMETIC` picks another
//! setting) and measures the reference's own chaos with an ensemble: its replays nudged
//! by +-1e-9 m and under two other arithmetic settings. Where every run of the ensemble
//! gives the same verdict, ours must be the same step; where the reference is chaotic,
//! within the extension of its runs' steps. Our state must equal the reference's to
//! rounding until its own runs depart from it (issue #33).

use std::path::{Path, PathBuf};

use std::collections::BTreeMap;

use dexjoco_augment::{AugmentConfig, augment};
use dexjoco_core::{Episode, TaskSpec};
use dexjoco_formats::raw::write_replay_zarr;
use dexjoco_render::RenderSettings;
use dexjoco_scripted::{self as scripted, PLANNED_TASKS, Variant};
use dexjoco_sim::{SceneSource, TaskEnv, load_task_scene};
use rand::{Rng, SeedableRng};
use serde_json::Value;

/// The seed of the resets planned here (used by no other test).
const SEED: u64 = 2525;
/// Steps the last action is repeated after the recording (augment's default).
const EXTEND: usize = 30;
/// The reference's own sensitivity: metres added to its arm position targets.
const NUDGE: f64 = 1e-9;
/// Our largest state difference from the reference's while the reference is not chaotic
/// (until 10 steps before its nudged replay departs from it by 1e-6): rounding level,
/// hand joints being stored as float32.
const CALM: f64 = 1e-6;

/// One episode replayed on both sides, and what our side did with it.
struct Case {
    name: String,
    spec: TaskSpec,
    /// Our trajectory: the recording the plan made (a replay reproduces it bit for bit,
    /// `scripted_tasks.rs`, and through augment below).
    ours: Episode,
    first_success: Option<usize>,
    first_failure: Option<usize>,
}

fn reference_scene(spec: &TaskSpec) -> dexjoco_sim::Scene {
    let source = SceneSource::Dir(dexjoco_testkit::reference_scene_dir());
    load_task_scene(&source, spec).unwrap_or_else(|e| panic!("{}: {e}", spec.id))
}

/// The demonstration (or wrong plan) of `task` from a seeded reset of the reference
/// scene, as the planner made it (success or not).
fn case(task: &str, variant: Variant) -> Case {
    let spec = TaskSpec::builtin(task).expect("a built-in task").clone();
    let scene = reference_scene(&spec);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(SEED);
    let s0 = TaskEnv::sample_initial_state(&scene, &spec, &mut || rng.random::<f64>()).unwrap();
    let suffix = if variant == Variant::Wrong {
        "wrong"
    } else {
        "demo"
    };
    let name = format!("{task}_{suffix}");
    let planned = scripted::plan(&scene, &spec, &s0, &name, variant)
        .unwrap_or_else(|e| panic!("{name}: no plan on the reference scene: {e}"));
    // A successful plan on the reference scene goes through every subtask, the last
    // ending on the success step, each near the planner's own phase end.
    if let Some(at) = planned.success_at {
        let ends: Vec<Option<usize>> = planned.subtasks.iter().map(|s| s.end).collect();
        assert!(
            ends.iter().all(Option::is_some) && ends.last() == Some(&Some(at)),
            "{name}: subtasks {:?}",
            planned.subtasks
        );
        assert_eq!(
            planned.phase_disagreements(),
            Vec::<String>::new(),
            "{name}"
        );
    }
    Case {
        first_failure: planned.failed.then(|| planned.episode.len() - 1),
        first_success: planned.success_at,
        ours: planned.episode,
        name,
        spec,
    }
}

/// Plans every `(task, variant)` on the machine's two cores (each plan is independent and
/// deterministic), in the order given.
fn plan_all(wanted: &[(&str, Variant)]) -> Vec<Case> {
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut planned: Vec<(usize, Case)> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..2)
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(&(task, variant)) = wanted.get(i) else {
                            return mine;
                        };
                        mine.push((i, case(task, variant)));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().unwrap())
            .collect()
    });
    planned.sort_by_key(|(i, _)| *i);
    planned.into_iter().map(|(_, c)| c).collect()
}

/// The arithmetic settings of the reference side that every x86-64 CPU with AVX2 runs
/// (`tests/python/reference_arithmetic.py`); the two that differ from the primary's run
/// each episode plainly as members of the ensemble.
const EVERY_CPU: [&str; 3] = ["avx2", "sandybridge", "baseline"];

/// The reference's runs: the primary (the arithmetic the harness pins, or the one
/// `$DEXJOCO_REFERENCE_ARITHMETIC` names) and its ensemble, the reference's own
/// perturbations that measure its chaos: the primary's replays with the arm targets
/// nudged by +-[`NUDGE`], and plain replays under two other arithmetic settings (another
/// rounding of the same computation, as another CPU would give). Four processes (two at a
/// time, the machine's two cores); one summary per job, in order.
fn replay_reference(jobs: &[Value], dir: &Path) -> (String, Vec<Value>) {
    let primary = dexjoco_testkit::reference_arithmetic();
    let members: Vec<&str> = EVERY_CPU
        .iter()
        .copied()
        .filter(|a| *a != primary)
        .take(2)
        .collect();
    let write = |name: &str, jobs: &[Value]| {
        let file = dir.join(name);
        fs_err::write(&file, serde_json::to_vec(jobs).unwrap()).unwrap();
        file
    };
    let batch = |file: PathBuf, arithmetic: String, tag: String| {
        let out = dir.to_owned();
        move || {
            dexjoco_testkit::run_reference_python_as(
                "dexjoco_reference.py",
                &[
                    "batch",
                    "--jobs",
                    file.to_str().unwrap(),
                    "--out",
                    out.to_str().unwrap(),
                    "--tag",
                    &tag,
                ],
                &arithmetic,
            );
        }
    };
    let all = write("jobs.json", jobs);
    let halves: Vec<PathBuf> = jobs
        .chunks(jobs.len().div_ceil(2))
        .enumerate()
        .map(|(i, half)| write(&format!("jobs-{i}.json"), half))
        .collect();
    let plain: Vec<Value> = jobs
        .iter()
        .map(|j| {
            let mut j = j.clone();
            j["nudges"] = serde_json::json!([]);
            j
        })
        .collect();
    let plain = write("jobs-plain.json", &plain);
    std::thread::scope(|s| {
        for half in &halves {
            s.spawn(batch(half.clone(), primary.clone(), "primary".into()));
        }
    });
    std::thread::scope(|s| {
        for m in &members {
            s.spawn(batch(plain.clone(), m.to_string(), m.to_string()));
        }
    });
    let stdout = dexjoco_testkit::run_reference_python_as(
        "dexjoco_reference.py",
        &[
            "summarize",
            "--jobs",
            all.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
            "--primary",
            "primary",
            "--members",
            &members.join(","),
        ],
        &primary,
    );
    (primary, serde_json::from_str(&stdout).unwrap())
}

fn step(v: &Value) -> Option<usize> {
    v.as_u64().map(|s| s as usize)
}

/// Our verdict step against the reference ensemble's (`runs[0]` the primary): where
/// every run of the ensemble agrees, the same step (or no verdict); where the reference
/// is chaotic (its own runs disagree), within the extension of the steps its runs gave,
/// or no verdict where one of its runs gave none too.
fn verdict_agrees(ours: Option<usize>, ensemble: &[Option<usize>]) -> bool {
    if ensemble.iter().all(|s| *s == ensemble[0]) {
        return ours == ensemble[0];
    }
    let steps: Vec<usize> = ensemble.iter().flatten().copied().collect();
    match ours {
        None => steps.len() < ensemble.len(),
        Some(o) => {
            let (lo, hi) = (steps.iter().min().unwrap(), steps.iter().max().unwrap());
            o + EXTEND >= *lo && o <= hi + EXTEND
        }
    }
}

/// Checks one case against the reference's summary; returns its table row and problems.
fn check(c: &Case, s: &Value, problems: &mut Vec<String>) -> String {
    let runs = s["runs"].as_array().unwrap();
    let successes: Vec<Option<usize>> = runs.iter().map(|r| step(&r["first_success"])).collect();
    let failures: Vec<Option<usize>> = runs.iter().map(|r| step(&r["first_failure"])).collect();
    if !verdict_agrees(c.first_success, &successes) {
        problems.push(format!(
            "{}: success at {:?}, the reference's at {:?} (its ensemble: {successes:?})",
            c.name, c.first_success, successes[0]
        ));
    }
    if !verdict_agrees(c.first_failure, &failures) {
        problems.push(format!(
            "{}: failure at {:?}, the reference's at {:?} (its ensemble: {failures:?})",
            c.name, c.first_failure, failures[0]
        ));
    }
    if c.name.ends_with("_demo") && c.first_success.is_some() {
        let failing: Vec<String> = runs
            .iter()
            .filter(|r| r["first_success"].is_null())
            .map(describe_run)
            .collect();
        if !failing.is_empty() {
            let why = FRAGILE_IN_REFERENCE.iter().find(|(n, _)| *n == c.name);
            println!(
                "{}: the reference does not succeed in {}: {}",
                c.name,
                failing.join(", "),
                why.map_or("not explained", |(_, why)| why)
            );
            if successes[0].is_none() && why.is_none() {
                problems.push(format!(
                    "{}: our plan succeeds, the reference's replay of it does not ({})",
                    c.name, failing[0]
                ));
            }
        }
    }
    let ours = s["ours"]["max_diff"].as_f64().unwrap();
    let own = s["self"]["max_diff"].as_f64().unwrap();
    let calm = s["ours"]["max_diff_while_calm"].as_f64().unwrap();
    if calm > CALM {
        problems.push(format!(
            "{}: state {calm:.3e} from the reference's before the reference's own runs depart from it",
            c.name
        ));
    }
    let show = |v: Option<usize>| v.map_or("-".to_owned(), |s| s.to_string());
    let verdicts: Vec<Option<usize>> = successes
        .iter()
        .zip(&failures)
        .map(|(s, f)| s.or(*f))
        .collect();
    format!(
        "| {} | {} | {} | {} | {} | {:.1e} ({} steps) | {:.1e} | {:.1e} |",
        c.name,
        show(c.first_success.or(c.first_failure)),
        show(verdicts[0]),
        verdicts[1..]
            .iter()
            .map(|v| show(*v))
            .collect::<Vec<_>>()
            .join(", "),
        if c.first_success.or(c.first_failure) == verdicts[0] {
            "yes"
        } else {
            "no"
        },
        calm,
        s["ours"]["calm_steps"],
        ours,
        own,
    )
}

/// One run of the reference's ensemble in words.
fn describe_run(r: &Value) -> String {
    let nudge = r["nudge"].as_f64().unwrap_or(0.0);
    if nudge == 0.0 {
        format!("the {} arithmetic", r["tag"].as_str().unwrap_or("?"))
    } else {
        format!("the primary nudged by {nudge:+e} m")
    }
}

/// Demonstrations whose plan succeeds on our side but whose replay in the reference
/// code does not succeed in every run of the ensemble, and why (measured; printed with
/// the table). Only a plan listed here may fail in the reference's primary run.
const FRAGILE_IN_REFERENCE: &[(&str, &str)] = &[
    (
        "bimanual_assembly_demo",
        "the let-go peg stands on the hole's flat bottom on one contact point (a cylinder's \
         flat end on a box, multi-point collision off) and rocks, lifting off for one step \
         at each swing; whether the reference counts 30 steps of contact in a row within \
         the 30-step extension is decided by rounding (succeeds at 1016 to 1047 or not at \
         all across the arithmetic settings: docs/reference-parity.md)",
    ),
    (
        "bimanual_microwave_cook_demo",
        "the recording ends on the start button's first touch, so its last target (repeated \
         by the extension) presses no deeper than that touch; where a perturbation has moved \
         the arm's path or the microwave by a millimetre or two, the fingertip stops 1.4 mm \
         short of the button (measured under the avx512 setting nudged by -1e-9 m)",
    ),
];

/// Every successful demonstration replayed through `augment` on the reference scenes
/// (one replay, the task's first camera, 32 px): success on the plan's last step, state
/// deviation 0.
fn replay_through_augment(cases: &[Case], dir: &Path) {
    let mut by_camera: BTreeMap<String, Vec<&Case>> = BTreeMap::new();
    for c in cases
        .iter()
        .filter(|c| c.first_success.is_some() && c.name.ends_with("_demo"))
    {
        by_camera
            .entry(c.spec.cameras[0].camera.clone())
            .or_default()
            .push(c);
    }
    for (camera, group) in by_camera {
        let input = dir.join(format!("augment-in-{camera}"));
        for c in &group {
            let mut ep = c.ours.clone();
            ep.arrays.retain(|k, _| k != Episode::ACTION_ROTVEC);
            write_replay_zarr(&input.join(&c.spec.id).join("episode_000000"), &ep).unwrap();
        }
        let config = AugmentConfig {
            replays: 1,
            seed: 3,
            scene: SceneSource::Dir(dexjoco_testkit::reference_scene_dir()),
            cameras: vec![camera.clone()],
            settings: RenderSettings {
                width: 32,
                height: 32,
                ..RenderSettings::default()
            },
            contact_sheet: false,
            extend_steps: 0,
            ..AugmentConfig::new(vec![input], dir.join(format!("augment-out-{camera}")))
        };
        let report = augment(&config, &dexjoco_core::NoProgress).unwrap();
        assert_eq!(report.episodes.len(), group.len(), "{:?}", report.skipped);
        for (e, c) in report.episodes.iter().zip(&group) {
            assert!(e.success, "{}: the augment replay did not succeed", c.name);
            assert_eq!(e.first_success, c.first_success, "{}: same step", c.name);
            assert_eq!(
                e.max_state_deviation, 0.0,
                "{}: replay != recording",
                c.name
            );
        }
    }
}

#[test]
fn every_task_replays_as_the_reference_replays_it() {
    let dir = tempfile::tempdir().unwrap();
    let mut wanted: Vec<(&str, Variant)> =
        PLANNED_TASKS.iter().map(|t| (*t, Variant::Demo)).collect();
    for task in ["bimanual_hanoi", "bimanual_unlock_ipad", "water_plant"] {
        wanted.push((task, Variant::Wrong));
    }
    let cases = plan_all(&wanted);
    let mut jobs = Vec::new();
    for c in &cases {
        let recording = dir.path().join(&c.name);
        let mut recorded = c.ours.clone();
        recorded.arrays.retain(|k, _| k != Episode::ACTION_ROTVEC);
        write_replay_zarr(&recording, &recorded).unwrap();
        jobs.push(serde_json::json!({
            "name": c.name, "task": c.spec.id, "episode": recording, "extend": EXTEND,
            "step_cap": c.spec.step_cap, "nudges": [NUDGE, -NUDGE], "ours": recording,
        }));
    }
    for c in cases.iter().filter(|c| c.name.ends_with("_demo")) {
        assert!(
            c.first_success.is_some(),
            "{}: the plan on the reference scene did not succeed",
            c.name
        );
    }
    replay_through_augment(&cases, dir.path());
    let (primary, summaries) = replay_reference(&jobs, dir.path());
    let mut problems = Vec::new();
    let members: Vec<String> = summaries[0]["runs"].as_array().unwrap()[1..]
        .iter()
        .map(describe_run)
        .collect();
    println!(
        "The reference under the {primary} arithmetic; its ensemble: {}.",
        members.join("; ")
    );
    println!(
        "| episode | ours: success (or failure) step | reference | the reference's ensemble | same step | \
         max state difference until 10 steps before the first ensemble run departs by 1e-6 | max state difference | \
         the ensemble's own |"
    );
    println!("|---|---:|---:|---:|---|---:|---:|---:|");
    for (c, s) in cases.iter().zip(&summaries) {
        println!("{}", check(c, s, &mut problems));
    }
    if std::env::var_os("DEXJOCO_PARITY_KEEP").is_some() {
        eprintln!(
            "episodes and reference trajectories kept in {}",
            dir.keep().display()
        );
    }
    assert!(problems.is_empty(), "{problems:#?}");
}
