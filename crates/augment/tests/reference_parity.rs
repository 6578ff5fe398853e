//! Simulation parity with the DexJoCo reference code itself: the same episodes replayed by
//! the reference replay script (`scripts/replay_demos_zarr.py`, its environments run
//! headless under MuJoCo 3.17.0 by `tests/python/dexjoco_reference.py`) and by our
//! `TaskEnv`, on the reference scenes, for all 11 tasks: a demonstration planned by
//! `scripted` from one seeded reset, and the deliberately wrong plans. Each
//! demonstration that succeeds is also replayed through `augment` (issue #26). Same success and failure verdicts on the same step (within
//! the extension where the reference's own success step moves when its arm targets are
//! nudged by 1e-9 m), and a state trajectory no further from the reference's than the
//! reference's own under that nudge.

use std::path::Path;

use std::collections::BTreeMap;

use dexjoco_augment::{AugmentConfig, augment};
use dexjoco_core::{Episode, TaskSpec};
use dexjoco_formats::raw::write_replay_zarr;
use dexjoco_sim::scripted::{self, PLANNED_TASKS, Variant};
use dexjoco_sim::{RenderQuality, RenderSettings, SceneSource, TaskEnv, load_task_scene};
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

/// Runs the reference replays of `jobs` in two processes (the machine's two cores).
fn replay_reference(jobs: &[Value], dir: &Path) -> Vec<Value> {
    let halves: Vec<&[Value]> = jobs.chunks(jobs.len().div_ceil(2)).collect();
    std::thread::scope(|s| {
        let handles: Vec<_> = halves
            .iter()
            .enumerate()
            .map(|(i, half)| {
                let file = dir.join(format!("jobs-{i}.json"));
                fs_err::write(&file, serde_json::to_vec(half).unwrap()).unwrap();
                let out = dir.to_owned();
                s.spawn(move || {
                    let stdout = dexjoco_testkit::run_reference_python(
                        "dexjoco_reference.py",
                        &[
                            "batch",
                            "--jobs",
                            file.to_str().unwrap(),
                            "--out",
                            out.to_str().unwrap(),
                        ],
                    );
                    serde_json::from_str::<Vec<Value>>(&stdout).unwrap()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    })
}

fn step(v: &Value) -> Option<usize> {
    v.as_u64().map(|s| s as usize)
}

/// Our verdict step against the reference's: the same, or within the extension where the
/// nudged reference's own step moved.
fn verdict_agrees(ours: Option<usize>, plain: Option<usize>, nudged: Option<usize>) -> bool {
    match (ours, plain) {
        (None, None) => true,
        (Some(o), Some(p)) if plain == nudged => o == p,
        (Some(o), Some(p)) => o.abs_diff(p) <= EXTEND,
        _ => false,
    }
}

/// Checks one case against the reference's summary; returns its table row and problems.
fn check(c: &Case, s: &Value, problems: &mut Vec<String>) -> String {
    let (plain, nudged) = (&s["runs"][0], &s["runs"][1]);
    let (ref_success, ref_nudged) = (
        step(&plain["first_success"]),
        step(&nudged["first_success"]),
    );
    let ref_failure = step(&plain["first_failure"]);
    if !verdict_agrees(c.first_success, ref_success, ref_nudged) {
        problems.push(format!(
            "{}: success at {:?}, the reference's at {ref_success:?} (nudged {ref_nudged:?})",
            c.name, c.first_success
        ));
    }
    if !verdict_agrees(c.first_failure, ref_failure, step(&nudged["first_failure"])) {
        problems.push(format!(
            "{}: failure at {:?}, the reference's at {ref_failure:?}",
            c.name, c.first_failure
        ));
    }
    let ours = s["ours"]["max_diff"].as_f64().unwrap();
    let own = s["self"]["max_diff"].as_f64().unwrap();
    let calm = s["ours"]["max_diff_while_calm"].as_f64().unwrap();
    if calm > CALM && !DEPARTS_EARLY.contains(&c.name.as_str()) {
        problems.push(format!(
            "{}: state {calm:.3e} from the reference's before the reference departs from itself",
            c.name
        ));
    }
    let show = |v: Option<usize>| v.map_or("-".to_owned(), |s| s.to_string());
    format!(
        "| {} | {} | {} | {} | {} | {:.1e} ({} steps) | {:.1e} | {:.1e} |",
        c.name,
        show(c.first_success.or(c.first_failure)),
        show(ref_success.or(ref_failure)),
        show(ref_nudged.or(step(&nudged["first_failure"]))),
        if c.first_success.or(c.first_failure) == ref_success.or(ref_failure) {
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

/// Episodes where our state departs from the reference's (above 1e-6) before the
/// reference nudged by 1e-9 m departs from itself: not explained yet (reported in
/// docs/reference-parity.md; the verdicts agree).
const DEPARTS_EARLY: &[&str] = &["bimanual_assembly_demo"];

/// Tasks whose planner does not yet succeed on this reset of the reference scene (issue
/// #26 reports what resists); every other task's plan must succeed here.
const NOT_YET_PLANNED_ON_REFERENCE: &[&str] = &["fold_glasses"];

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
            inputs: vec![input],
            out: dir.join(format!("augment-out-{camera}")),
            replays: 1,
            seed: 3,
            tasks_dir: None,
            scene: SceneSource::Dir(dexjoco_testkit::reference_scene_dir()),
            camera_pool: None,
            cameras: vec![camera],
            settings: RenderSettings {
                width: 32,
                height: 32,
                quality: RenderQuality::FAST,
                depth: false,
                geometry: dexjoco_sim::Geometry::Full,
            },
            keep_failed: false,
            max_frames: None,
            resimulate_per_replay: false,
            contact_sheet: false,
            depth: false,
            dynamics: false,
            extend_steps: 0,
            shard: None,
            overwrite: false,
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
            "step_cap": c.spec.step_cap, "nudges": [NUDGE], "ours": recording,
        }));
    }
    for c in cases.iter().filter(|c| c.name.ends_with("_demo")) {
        let resists = NOT_YET_PLANNED_ON_REFERENCE.contains(&c.spec.id.as_str());
        assert!(
            resists || c.first_success.is_some(),
            "{}: the plan on the reference scene did not succeed",
            c.name
        );
    }
    replay_through_augment(&cases, dir.path());
    let summaries = replay_reference(&jobs, dir.path());
    let mut problems = Vec::new();
    println!(
        "| episode | ours: success (or failure) step | reference | reference, nudged {NUDGE:e} m | same step | \
         max state difference until 10 steps before the nudged reference departs by 1e-6 | max state difference | \
         the reference's own under the nudge |"
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
