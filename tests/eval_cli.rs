//! `dexjoco-data eval` against real openpi policy servers (openpi's own
//! `WebsocketPolicyServer`, run from the DexJoCo reference code by
//! `tests/python/policy_server.py`): an oracle that answers with the chunks of the plan
//! `scripted` made for the same reset succeeds on every task and is executed action for
//! action; misbehaving servers are named and leave no half episode; a killed run resumes;
//! worker processes give the same bytes; `stats` reads the output as it is.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use common::{PolicyServer as Server, dexjoco, free_port, processes_marked, said};
use dexjoco_core::TaskSet;

fn run(cmd: &mut Command) -> Output {
    cmd.output().unwrap()
}

/// `eval` of one task against the server, small renders, no videos.
fn eval(server: &Server, task: &str, out: &Path, extra: &[&str]) -> Output {
    run(dexjoco()
        .args(["-q", "eval", "--task", task, "--host", "127.0.0.1"])
        .args(["--port", &server.port.to_string()])
        .args(["--render-size", "32x32", "--quality", "fast", "--no-videos"])
        .args(["--privileged-keys", "--server-wait", "0"])
        .arg("--output")
        .arg(out)
        .args(extra))
}

/// `eval` of one episode of seed 3 with the modelled latency `latency`.
fn eval_latency(server: &Server, task: &str, out: &Path, latency: usize, extra: &[&str]) -> Output {
    let latency = latency.to_string();
    let args = [
        &[
            "--episodes",
            "1",
            "--seed",
            "3",
            "--latency-steps",
            &latency,
        ][..],
        extra,
    ]
    .concat();
    eval(server, task, out, &args)
}

/// `scripted`'s plan of the first reset of `seed` (None when it did not succeed).
fn plan(task: &str, seed: &str, plans: &Path, scene: Option<&Path>) -> Option<PathBuf> {
    let mut cmd = dexjoco();
    cmd.args([
        "-q",
        "scripted",
        "--task",
        task,
        "--episodes",
        "1",
        "--seed",
        seed,
    ])
    .arg("--out")
    .arg(plans);
    if let Some(s) = scene {
        cmd.arg("--scene-dir").arg(s);
    }
    let o = run(&mut cmd);
    let dir = plans.join(task).join("episode_000000");
    assert!(
        o.status.code().is_some_and(|c| c == 0 || c == 1),
        "{}",
        said(&o)
    );
    dir.is_dir().then_some(dir)
}

/// The one episode folder of an eval output, and its record.
fn episode(out: &Path, k: usize) -> (PathBuf, serde_json::Value) {
    let prefix = format!("episode_{k:02}_");
    let dir = fs_err::read_dir(out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with(&prefix)
        })
        .unwrap_or_else(|| panic!("no {prefix}* in {}", out.display()));
    let rec = serde_json::from_slice(&fs_err::read(dir.join("episode.json")).unwrap()).unwrap();
    (dir, rec)
}

/// The largest difference between the executed actions (the rollout's `action`) and the
/// plan's, from step `from` (the warm-up left out).
fn action_difference(rollout: &Path, plan: &Path, from: usize, warmup: usize) -> f64 {
    let tasks = TaskSet::builtin();
    let ev = dexjoco_formats::read_episode(rollout, tasks).unwrap();
    let pl = dexjoco_formats::read_episode(plan, tasks).unwrap();
    // As rotation vectors: a quaternion and its negative are one rotation.
    let (ea, pa) = (
        ev.array("action_rotvec").unwrap(),
        pl.array("action_rotvec").unwrap(),
    );
    let mut worst = 0.0f64;
    for t in from..pa.len().min(ea.len() - warmup) {
        for (a, b) in ea.row(t + warmup).iter().zip(pa.row(t)) {
            worst = worst.max((a - b).abs());
        }
    }
    worst
}

#[test]
fn an_oracle_policy_succeeds_on_every_task_through_the_protocol() {
    let tmp = tempfile::tempdir().unwrap();
    let plans = tmp.path().join("plans");
    let planned: Vec<(&str, Option<PathBuf>)> = dexjoco_scripted::PLANNED_TASKS
        .iter()
        .map(|t| (*t, plan(t, "3", &plans, None)))
        .collect();
    let server = Server::start(&["oracle", "--plans", plans.to_str().unwrap()]);
    let root = tmp.path().join("eval");
    let ipad = tmp.path().join("language/123/bimanual_unlock_ipad_seed3");
    for (task, plan) in &planned {
        let out = if *task == "bimanual_unlock_ipad" {
            ipad.clone()
        } else {
            root.join(format!("{task}_seed3"))
        };
        let o = eval(&server, task, &out, &["--episodes", "1", "--seed", "3"]);
        assert_eq!(o.status.code(), Some(0), "{task}: {}", said(&o));
        let (dir, rec) = episode(&out, 0);
        let Some(plan) = plan else {
            eprintln!(
                "{task}: no successful plan for this reset; eval gave {}",
                rec["success"]
            );
            continue;
        };
        assert_eq!(rec["success"], true, "{task}: {rec}");
        let warmup = rec["warmup_steps"].as_u64().unwrap() as usize;
        let plan_len = dexjoco_formats::read_episode(plan, TaskSet::builtin())
            .unwrap()
            .len();
        if warmup == 0 {
            // Latency 0: every chunk merged at its own step, the plan executed as planned.
            assert_eq!(rec["success_step"], plan_len - 1, "{task}: {rec}");
            let d = action_difference(&dir, plan, 0, 0);
            assert!(d < 1e-9, "{task}: executed actions {d:e} from the plan's");
        }
        assert!(out.join("success_rate_1_1.txt").is_file());
    }
    // The iPad's digits are in its folder's name, as the reference client writes them
    // (the digits of each press joined by `_`), and the language analysis reads them.
    let (dir, _) = episode(&ipad, 0);
    assert!(
        dir.ends_with("episode_00_success_1_2_3"),
        "{}",
        dir.display()
    );
    let o = run(dexjoco()
        .args(["stats", "--language-eval"])
        .arg(tmp.path().join("language"))
        .arg("--out")
        .arg(tmp.path().join("stats-language"))
        .arg("--json"));
    assert_eq!(o.status.code(), Some(0), "{}", said(&o));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let precision = &json["language_eval"]["precision"][0];
    assert_eq!(precision["expected"], "123", "{json}");
    assert_eq!(precision["episodes"], 1, "{json}");
    assert_eq!(precision["correct"], 1, "{json}");
    // stats reads the runs as they are.
    let o = run(dexjoco()
        .args(["stats", "--success-table"])
        .arg(&root)
        .arg("--out")
        .arg(tmp.path().join("stats")));
    let s = said(&o);
    assert_eq!(o.status.code(), Some(0), "{s}");
    for (task, plan) in &planned {
        // The iPad's run is under the language root, read by the analysis above.
        if plan.is_some() && *task != "bimanual_unlock_ipad" {
            assert!(
                s.contains(&dexjoco_stats::task_name(task)),
                "{task} missing: {s}"
            );
        }
    }
}

#[test]
fn with_a_latency_the_chunks_are_aligned_to_their_observations_on_the_reference_scenes() {
    let tmp = tempfile::tempdir().unwrap();
    let plans = tmp.path().join("plans");
    let scene = dexjoco_testkit::reference_scene_dir();
    let tasks = ["hammer_nail", "pick_bucket", "pinch_tongs", "water_plant"];
    let planned: Vec<PathBuf> = tasks
        .iter()
        .map(|t| plan(t, "3", &plans, Some(&scene)).expect("a successful plan"))
        .collect();
    let server = Server::start(&["oracle", "--plans", plans.to_str().unwrap()]);
    let latency = 4;
    for (task, plan) in tasks.iter().zip(&planned) {
        let out = tmp.path().join("eval").join(task);
        let o = eval_latency(
            &server,
            task,
            &out,
            latency,
            &["--scene-dir", scene.to_str().unwrap()],
        );
        assert_eq!(o.status.code(), Some(0), "{task}: {}", said(&o));
        let (dir, rec) = episode(&out, 0);
        assert_eq!(rec["success"], true, "{task}: {rec}");
        assert_eq!(rec["latency_steps"], latency);
        // The first chunk lands at step 4: the pose is held until then; from there on each
        // step executes the plan's action for that step (its first 4 rows expired).
        assert_eq!(rec["held_steps"], latency, "{task}: {rec}");
        let d = action_difference(&dir, plan, latency, 0);
        assert!(d < 1e-9, "{task}: executed actions {d:e} from the plan's");
    }
}

#[test]
fn overlapping_chunks_are_merged_as_the_reference_clients_buffer_merges_them() {
    // Each chunk is moved off the plan by its own small pattern, so where chunks overlap
    // the alignment, the blend weights and the rotation interpolation decide the executed
    // action; the reference client's own `receive_actions`, fed the same chunks at the same
    // steps, must execute the same actions.
    let tmp = tempfile::tempdir().unwrap();
    for (task, latency) in [("hammer_nail", 5), ("bimanual_unlock_ipad", 7)] {
        let plans = tmp.path().join("plans").join(task);
        let plan_dir = plan(task, "3", &plans, None).expect("a successful plan");
        let log = tmp.path().join(format!("{task}.jsonl"));
        let server = Server::start(&[
            "oracle",
            "--plans",
            plan_dir.to_str().unwrap(),
            "--perturb",
            "2e-3",
            "--log",
            log.to_str().unwrap(),
        ]);
        let out = tmp.path().join("eval").join(task);
        let o = eval_latency(&server, task, &out, latency, &[]);
        assert_eq!(o.status.code(), Some(0), "{task}: {}", said(&o));
        let (dir, rec) = episode(&out, 0);
        let merged = dexjoco_testkit::run_reference_python(
            "reference_chunk_merge.py",
            &[
                "--log",
                log.to_str().unwrap(),
                "--rollout",
                dir.join("replay.zarr").to_str().unwrap(),
                "--latency",
                &latency.to_string(),
            ],
        );
        let merged: serde_json::Value = serde_json::from_str(merged.trim()).unwrap();
        eprintln!("{task}: {merged}");
        let steps = rec["steps"].as_u64().unwrap();
        assert!(merged["merged"].as_u64().unwrap() > 5, "{task}: {merged}");
        assert_eq!(
            merged["held"].as_array().unwrap().len() as u64,
            rec["held_steps"].as_u64().unwrap(),
            "{task}: the steps the pose is held: {merged} {rec}"
        );
        assert_eq!(
            merged["compared"].as_u64().unwrap() + rec["held_steps"].as_u64().unwrap(),
            steps,
            "{task}: {merged}"
        );
        let d = merged["max_difference"].as_f64().unwrap();
        assert!(
            d < 1e-9,
            "{task}: executed actions {d:e} from the reference buffer's"
        );
    }
}

/// A server that answers a few chunks, then misbehaves as `how` says.
fn misbehaving(how: &str, after: usize) -> Server {
    Server::start(&["misbehave", "--how", how, "--after", &after.to_string()])
}

/// The names in a folder.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs_err::read_dir(dir)
        .map(|rd| {
            rd.map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

#[test]
fn a_bad_server_is_named_and_leaves_no_half_episode() {
    let tmp = tempfile::tempdir().unwrap();
    // Nobody listening: named, nothing written.
    let port = free_port();
    let out = tmp.path().join("none");
    let o = run(dexjoco()
        .args([
            "eval",
            "--task",
            "hammer_nail",
            "--episodes",
            "1",
            "--server-wait",
            "0",
        ])
        .args(["--host", "127.0.0.1", "--port", &port.to_string()])
        .arg("--output")
        .arg(&out));
    let s = said(&o);
    assert_eq!(o.status.code(), Some(1), "{s}");
    assert!(
        s.contains("cannot connect") && s.contains("hint: start a policy server"),
        "{s}"
    );
    assert!(!out.exists());
    for (how, expect, extra) in [
        ("shape", "shape (30, 21)", vec![]),
        ("nan", "row 3, column 4 is NaN", vec![]),
        (
            "silent",
            "no answer within the deadline",
            vec!["--deadline", "2"],
        ),
        ("error", "the policy failed on purpose", vec![]),
        (
            "close",
            "the connection ended while waiting for its answer",
            vec![],
        ),
    ] {
        let server = misbehaving(how, 2);
        let out = tmp.path().join(how);
        let mut args = vec!["--episodes", "1"];
        args.extend(&extra);
        let o = eval(&server, "hammer_nail", &out, &args);
        let s = said(&o);
        assert_eq!(o.status.code(), Some(1), "{how}: {s}");
        assert!(s.contains(expect), "{how}: {s}");
        assert!(
            names(&out)
                .iter()
                .all(|n| !n.starts_with("episode_") && n != ".staging"),
            "{how}: {:?}",
            names(&out)
        );
    }
}

#[test]
fn a_run_the_server_dropped_resumes_with_the_episodes_it_lacks() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    // Episode 0 runs to the step cap on held poses (about 140 chunks); the server dies
    // during episode 1.
    let server = misbehaving("close", 160);
    let o = eval(&server, "hammer_nail", &out, &["--episodes", "2"]);
    assert_eq!(o.status.code(), Some(1), "{}", said(&o));
    assert_eq!(
        names(&out),
        ["episode_00_failure"],
        "episode 0 kept, nothing of episode 1"
    );
    drop(server);
    let empty = tmp.path().join("no-plans");
    fs_err::create_dir_all(&empty).unwrap();
    let server = Server::start(&["oracle", "--plans", empty.to_str().unwrap()]);
    let o = eval(&server, "hammer_nail", &out, &["--episodes", "2"]);
    let s = said(&o);
    assert_eq!(o.status.code(), Some(0), "{s}");
    assert!(s.contains("1 evaluated now"), "{s}");
    assert!(
        out.join("success_rate_0_2.txt").is_file(),
        "{:?}",
        names(&out)
    );
    // Another seed into the same folder is refused.
    let o = eval(
        &server,
        "hammer_nail",
        &out,
        &["--episodes", "2", "--seed", "9"],
    );
    assert_eq!(o.status.code(), Some(2), "{}", said(&o));
}

#[test]
fn worker_processes_give_the_same_rollouts() {
    let tmp = tempfile::tempdir().unwrap();
    let plans = tmp.path().join("plans");
    let o = run(dexjoco()
        .args([
            "-q",
            "scripted",
            "--task",
            "hammer_nail",
            "--episodes",
            "2",
            "--seed",
            "4",
        ])
        .arg("--out")
        .arg(&plans));
    assert_eq!(o.status.code(), Some(0), "{}", said(&o));
    let server = Server::start(&["oracle", "--plans", plans.to_str().unwrap()]);
    let runs: Vec<PathBuf> = ["1", "2"]
        .iter()
        .map(|j| {
            let out = tmp.path().join(format!("j{j}"));
            let o = eval(
                &server,
                "hammer_nail",
                &out,
                &[
                    "--episodes",
                    "2",
                    "--seed",
                    "4",
                    "--latency-steps",
                    "2",
                    "-j",
                    j,
                ],
            );
            assert_eq!(o.status.code(), Some(0), "-j {j}: {}", said(&o));
            out
        })
        .collect();
    assert_eq!(names(&runs[0]), names(&runs[1]));
    for k in 0..2 {
        let (a, ra) = episode(&runs[0], k);
        let (b, rb) = episode(&runs[1], k);
        let strip = |mut r: serde_json::Value| {
            r.as_object_mut().unwrap().remove("inference_seconds");
            r
        };
        assert_eq!(strip(ra), strip(rb), "episode {k}");
        for f in ["replay.zarr/data/action/0.0", "replay.zarr/data/state/0.0"] {
            assert_eq!(
                fs_err::read(a.join(f)).unwrap(),
                fs_err::read(b.join(f)).unwrap(),
                "episode {k}: {f}"
            );
        }
    }
}

#[test]
fn our_first_observation_is_the_reference_clients() {
    let tmp = tempfile::tempdir().unwrap();
    let config = dexjoco_testkit::upstream_dir().join("task-configs/rand_obj/hammer_nail.yaml");
    let state = tmp.path().join("state.json");
    let (theirs, ours) = (tmp.path().join("theirs.npz"), tmp.path().join("ours.npz"));
    // The reference client's own env wrapper and websocket client, rendering with EGL,
    // from a reset of seed 0; the server keeps the first observation.
    let server = Server::start(&["record", "--out", theirs.to_str().unwrap(), "--close"]);
    dexjoco_testkit::run_reference_python(
        "reference_client_observation.py",
        &[
            "--config",
            config.to_str().unwrap(),
            "--seed",
            "0",
            "--port",
            &server.port.to_string(),
            "--state-out",
            state.to_str().unwrap(),
        ],
    );
    drop(server);
    // Ours from the same scene state (the server ends at our second observation).
    let server = Server::start(&["record", "--out", ours.to_str().unwrap(), "--close"]);
    let o = run(dexjoco()
        .args([
            "-q",
            "eval",
            "--config",
            config.to_str().unwrap(),
            "--episodes",
            "1",
        ])
        .args(["--host", "127.0.0.1", "--port", &server.port.to_string()])
        .args(["--no-videos", "--server-wait", "0", "--resets-from"])
        .arg(&state)
        .arg("--scene-dir")
        .arg(dexjoco_testkit::reference_scene_dir())
        .arg("--output")
        .arg(tmp.path().join("out")));
    assert_eq!(
        o.status.code(),
        Some(1),
        "ends when the server does: {}",
        said(&o)
    );
    let out = dexjoco_testkit::run_python(
        "compare_observations.py",
        &[theirs.to_str().unwrap(), ours.to_str().unwrap()],
    );
    let cmp: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(cmp["keys_equal"], true, "{cmp}");
    assert_eq!(cmp["prompt_equal"], true, "{cmp}");
    assert_eq!(cmp["state_max_diff"], 0.0, "{cmp}");
    for k in ["base", "wrist"] {
        assert_eq!(cmp["images"][k]["shape_equal"], true, "{cmp}");
        assert!(
            cmp["images"][k]["max_diff"].as_u64().unwrap() <= 1,
            "{k}: {cmp}"
        );
    }
}

#[test]
fn an_unreadable_record_is_named_and_its_episode_not_evaluated_again() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let server = Server::start(&["hold"]);
    let args = ["--episodes", "2", "--step-cap", "20"];
    let o = eval(&server, "hammer_nail", &out, &args);
    assert_eq!(o.status.code(), Some(0), "{}", said(&o));
    let (dir, _) = episode(&out, 0);
    let record = dir.join("episode.json");
    let bytes = fs_err::read(&record).unwrap();
    let before = names(&out);
    for (what, expect) in [
        ("truncated", "EOF while parsing"),
        ("missing", "the episode folder has no record"),
    ] {
        match what {
            "truncated" => fs_err::write(&record, &bytes[..bytes.len() / 2]).unwrap(),
            _ => fs_err::remove_file(&record).unwrap(),
        }
        let o = eval(&server, "hammer_nail", &out, &args);
        let s = said(&o);
        assert_eq!(o.status.code(), Some(1), "{what}: {s}");
        assert!(
            s.contains(&record.display().to_string())
                && s.contains(expect)
                && s.contains("delete its folder"),
            "{what}: {s}"
        );
        assert_eq!(names(&out), before, "{what}: nothing evaluated again");
    }
    // Deleting the folder, as the error says, evaluates that episode again.
    fs_err::remove_dir_all(&dir).unwrap();
    let o = eval(&server, "hammer_nail", &out, &args);
    let s = said(&o);
    assert_eq!(o.status.code(), Some(0), "{s}");
    assert!(s.contains("1 evaluated now"), "{s}");
    assert_eq!(names(&out), before);
    // One run's folder, whatever its name, is read as a run (from its eval_run.json).
    let o = run(dexjoco()
        .args(["stats", "--success-table"])
        .arg(&out)
        .arg("--out")
        .arg(tmp.path().join("stats")));
    let s = said(&o);
    assert_eq!(o.status.code(), Some(0), "{s}");
    assert!(s.contains("| Hammer Nail | 0.0 ± n/a |"), "{s}");
}

/// Starts `eval -j 2` of 3 episodes in the background, marked; returns it once a worker
/// is mid-episode (its staging folder exists), with the workers' pids.
fn eval_with_workers_mid_episode(
    server: &Server,
    out: &Path,
    mark: &str,
) -> (std::process::Child, Vec<u32>) {
    let child = dexjoco()
        .env("DEXJOCO_TEST_MARK", mark)
        .args(["eval", "--task", "hammer_nail", "-j", "2"])
        .args(["--episodes", "3", "--step-cap", "300", "--seed", "2"])
        .args(["--render-size", "32x32", "--no-videos", "--quality", "fast"])
        .args(["--host", "127.0.0.1", "--port", &server.port.to_string()])
        .args(["--server-wait", "0", "--output"])
        .arg(out)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    while !out.join(".staging").is_dir()
        || fs_err::read_dir(out.join(".staging")).map_or(0, |d| d.count()) == 0
    {
        assert!(started.elapsed().as_secs() < 120, "no episode started");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let workers = processes_marked(mark, "eval-worker");
    assert!(!workers.is_empty(), "no worker process found");
    (child, workers)
}

#[test]
fn a_worker_killed_mid_episode_is_replaced_and_its_episode_redone() {
    let tmp = tempfile::tempdir().unwrap();
    let server = Server::start(&["hold"]);
    // A worker killed mid-episode: its episode goes to a fresh worker.
    let out = tmp.path().join("killed-worker");
    let mark = format!("worker-{}", std::process::id());
    let (child, workers) = eval_with_workers_mid_episode(&server, &out, &mark);
    assert!(
        Command::new("kill")
            .args(["-KILL", &workers[0].to_string()])
            .status()
            .unwrap()
            .success()
    );
    let o = child.wait_with_output().unwrap();
    let s = said(&o);
    assert_eq!(o.status.code(), Some(0), "{s}");
    // Killed mid-episode, or (on a loaded machine) before its renderer drew: either way
    // its episode goes to another worker and the run completes.
    assert!(
        s.contains("episode 0 failed, retrying it once")
            || s.contains("episode 1 failed, retrying it once")
            || s.contains("goes to another worker"),
        "{s}"
    );
    assert!(s.contains("3 evaluated now"), "{s}");
    assert!(!out.join(".staging").exists(), "{:?}", names(&out));
    // The parent killed mid-episode: its workers end at their next step, nothing is
    // committed without it, and the rerun completes the run.
    let again = tmp.path().join("killed-parent");
    let mark = format!("parent-{}", std::process::id());
    let (mut child, _) = eval_with_workers_mid_episode(&server, &again, &mark);
    child.kill().unwrap();
    child.wait().unwrap();
    let started = std::time::Instant::now();
    while !processes_marked(&mark, "eval-worker").is_empty() {
        assert!(
            started.elapsed().as_secs() < 10,
            "workers outlived their run"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let o = eval(
        &server,
        "hammer_nail",
        &again,
        &["--episodes", "3", "--step-cap", "300", "--seed", "2"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", said(&o));
    assert!(!again.join(".staging").exists());
    // Both runs hold the rollouts of an uninterrupted one.
    let whole = tmp.path().join("whole");
    let o = eval(
        &server,
        "hammer_nail",
        &whole,
        &["--episodes", "3", "--step-cap", "300", "--seed", "2"],
    );
    assert_eq!(o.status.code(), Some(0), "{}", said(&o));
    for run in [&out, &again] {
        assert_eq!(names(run), names(&whole));
        for k in 0..3 {
            let (a, _) = episode(run, k);
            let (b, _) = episode(&whole, k);
            for f in ["replay.zarr/data/action/0.0", "replay.zarr/data/state/0.0"] {
                assert_eq!(
                    fs_err::read(a.join(f)).unwrap(),
                    fs_err::read(b.join(f)).unwrap(),
                    "{}: episode {k}: {f}",
                    run.display()
                );
            }
        }
    }
}

#[test]
fn a_policy_that_stops_after_the_first_subtask_shows_it_complete_and_the_rest_not() {
    let tmp = tempfile::tempdir().unwrap();
    let plans = tmp.path().join("plans");
    let plan = plan("hammer_nail", "5", &plans, None).expect("a plan that succeeds");
    let record: serde_json::Value =
        serde_json::from_slice(&fs_err::read(plan.join("plan.json")).unwrap()).unwrap();
    let first_end = record["subtasks"][0]["end"].as_u64().unwrap() as usize;
    let server = Server::start(&[
        "oracle",
        "--plans",
        plans.to_str().unwrap(),
        "--cut-after-first-subtask",
    ]);
    let out = tmp.path().join("policies/cut/hammer_nail_seed5");
    let cap = (first_end + 150).to_string();
    let o = eval(
        &server,
        "hammer_nail",
        &out,
        &["--episodes", "1", "--seed", "5", "--step-cap", &cap],
    );
    assert_eq!(o.status.code(), Some(0), "{}", said(&o));
    let (_, rec) = episode(&out, 0);
    assert_eq!(rec["success"], false);
    let spans = rec["subtasks"].as_array().unwrap();
    let ends: Vec<Option<u64>> = spans.iter().map(|s| s["end"].as_u64()).collect();
    assert_eq!(ends, [Some(first_end as u64), None, None], "{spans:?}");
    // The success table's subtask progress: the first complete, the others not.
    let o = run(dexjoco()
        .args(["stats", "--success-table"])
        .arg(tmp.path().join("policies"))
        .arg("--out")
        .arg(tmp.path().join("stats")));
    let s = said(&o);
    assert_eq!(o.status.code(), Some(0), "{s}");
    assert!(
        s.contains(
            "| cut | rand-obj | Hammer Nail | 1 | grasp the hammer 1 (100 %); \
             strike the nail with the hammer 0 (0 %); drive the nail into the board 0 (0 %) | \
             1.00 of 3 |"
        ),
        "{s}"
    );
}

#[test]
fn evaluated_rollouts_convert_to_a_dataset_with_their_videos_and_verdicts() {
    let tmp = tempfile::tempdir().unwrap();
    let plans = tmp.path().join("plans");
    let plan = plan("hammer_nail", "5", &plans, None).expect("a plan that succeeds");
    let record: serde_json::Value =
        serde_json::from_slice(&fs_err::read(plan.join("plan.json")).unwrap()).unwrap();
    let cap = (record["success_step"].as_u64().unwrap() + 40).to_string();
    let server = Server::start(&["oracle", "--plans", plans.to_str().unwrap()]);
    // Episode 0 follows the plan and succeeds; episode 1 (another reset, no plan) holds
    // its pose to the cap. Videos on.
    let out = tmp.path().join("eval/hammer_nail_seed5");
    let o = run(dexjoco()
        .args(["-q", "eval", "--task", "hammer_nail", "--host", "127.0.0.1"])
        .args(["--port", &server.port.to_string()])
        .args(["--render-size", "32x32", "--quality", "fast"])
        .args(["--privileged-keys", "--server-wait", "0"])
        .args(["--episodes", "2", "--seed", "5", "--step-cap", &cap])
        .arg("--output")
        .arg(&out));
    assert_eq!(o.status.code(), Some(0), "{}", said(&o));
    let (d0, r0) = episode(&out, 0);
    let (d1, r1) = episode(&out, 1);
    assert_eq!(
        (r0["success"].clone(), r1["success"].clone()),
        (true.into(), false.into())
    );

    // convert: both rollouts (the failure too: its verdict is a label), their videos.
    let ds = tmp.path().join("rollouts");
    let o = common::succeeds(
        dexjoco()
            .args(["convert", "--no-skip-static", "--out"])
            .arg(&ds)
            .arg(&out),
    );
    let steps = |r: &serde_json::Value| r["steps"].as_u64().unwrap() as usize;
    let (n0, n1) = (steps(&r0), steps(&r1));
    assert!(
        said(&o).contains(&format!("2 episodes, {} frames", n0 + n1)),
        "{}",
        said(&o)
    );
    dexjoco_testkit::lerobot_doctor_passes(&ds);
    // Each episode's video frames are the rollout's, but the one after its last step.
    for camera in ["front", "wrist"] {
        let file = ds.join(format!(
            "videos/observation.images.{camera}/chunk-000/file-000.mp4"
        ));
        let got = dexjoco_video::decode_rgb(&file).unwrap();
        let mut want = dexjoco_video::decode_rgb(&d0.join(format!("{camera}.mp4"))).unwrap();
        assert_eq!(want.len(), n0 + 1);
        want.truncate(n0);
        let mut second = dexjoco_video::decode_rgb(&d1.join(format!("{camera}.mp4"))).unwrap();
        second.truncate(n1);
        want.extend(second);
        assert_eq!(got.len(), want.len(), "{camera}");
        let exact = got.iter().zip(&want).filter(|(a, b)| a == b).count();
        assert!(
            exact + 16 >= want.len(),
            "{camera}: {exact} of {} frames bit-exact",
            want.len()
        );
    }
    // The verdicts and subtask progress as per-episode labels, to filter by.
    let kept = |predicate: &str| -> u64 {
        let filtered = tmp.path().join("filtered");
        let _ = fs_err::remove_dir_all(&filtered);
        common::succeeds(
            dexjoco()
                .args(["-q", "dataset", "filter"])
                .arg(&ds)
                .args(["--where", predicate, "--out"])
                .arg(&filtered),
        );
        let info = common::succeeds(dexjoco().args(["dataset", "info", "--json"]).arg(&filtered));
        let info: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
        info["episodes"].as_u64().unwrap()
    };
    assert_eq!(kept("outcome/success == true"), 1);
    assert_eq!(kept("outcome/subtasks_done == 3"), 1);
    assert_eq!(kept("outcome/subtasks_done == 0"), 1);
    assert_eq!(kept("outcome/first_success >= 0"), 1);
}

/// A state-only evaluation (`--environment-state --no-cameras --no-videos`) renders
/// nothing (counted), and the environment state each observation carries is, bit for bit
/// (as the float32 a dataset stores), the row `convert --environment-state` writes for
/// the same step of the rollout: one function builds both. The plan's own environment
/// state (recorded by `scripted`) agrees along the way. lerobot 0.6.1 loads the feature
/// with its names and statistics, and ACT builds and trains with it as its only input
/// beside the proprioception.
#[test]
fn a_state_only_evaluation_renders_nothing_and_sends_the_datasets_environment_state() {
    let tmp = tempfile::tempdir().unwrap();
    let plans = tmp.path().join("plans");
    let plan = plan("hammer_nail", "5", &plans, None).expect("a plan that succeeds");
    let log = tmp.path().join("answers.jsonl");
    let server = Server::start(&[
        "oracle",
        "--plans",
        plans.to_str().unwrap(),
        "--log",
        log.to_str().unwrap(),
    ]);
    let out = tmp.path().join("eval");
    let o = run(dexjoco()
        .args(["-q", "eval", "--task", "hammer_nail", "--host", "127.0.0.1"])
        .args(["--port", &server.port.to_string()])
        .args(["--privileged-keys", "--environment-state", "--no-cameras"])
        .args(["--no-videos", "--server-wait", "0", "--episodes", "1"])
        .arg("--resets-from")
        .arg(&plan)
        .arg("--output")
        .arg(&out));
    assert_eq!(o.status.code(), Some(0), "{}", said(&o));
    let (dir, record) = episode(&out, 0);
    assert_eq!(record["success"], true, "{record}");
    assert_eq!(record["frames_rendered"], 0, "{record}");
    assert_eq!(
        dexjoco_testkit::file_tree(&dir)
            .keys()
            .filter(|k| k.ends_with(".mp4"))
            .count(),
        0
    );

    let ds = tmp.path().join("ds");
    common::succeeds(
        dexjoco()
            .args([
                "-q",
                "convert",
                "--no-skip-static",
                "--environment-state",
                "--out",
            ])
            .arg(&ds)
            .arg(&out),
    );
    let rows = dexjoco_testkit::run_python_json("lerobot_env_state.py", &[ds.to_str().unwrap()]);
    let column: Vec<Vec<f64>> = serde_json::from_value(rows["environment_state"].clone()).unwrap();
    let names: Vec<String> = serde_json::from_value(rows["names"].clone()).unwrap();
    let spec = dexjoco_core::TaskSpec::builtin("hammer_nail").unwrap();
    assert_eq!(names, spec.environment_state_names());
    let planned = dexjoco_formats::read_episode(&plan, TaskSet::builtin()).unwrap();
    let planned = planned
        .array("environment_state")
        .expect("scripted records it");
    let mut compared = 0;
    for line in fs_err::read_to_string(&log).unwrap().lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let step = v["step"].as_u64().unwrap() as usize;
        let sent: Vec<f64> = serde_json::from_value(v["environment_state"].clone()).unwrap();
        let stored = &column[step];
        for (a, b) in sent.iter().zip(stored) {
            assert_eq!(
                (*a as f32).to_bits(),
                (*b as f32).to_bits(),
                "step {step}: {sent:?} vs {stored:?}"
            );
        }
        if step < planned.len() {
            let close = planned
                .row(step)
                .iter()
                .zip(&sent)
                .all(|(p, s)| (p - s).abs() < 1e-6);
            assert!(
                close,
                "step {step}: the plan's {:?} vs {sent:?}",
                planned.row(step)
            );
        }
        compared += 1;
    }
    assert!(compared >= 3, "{compared} observations");
    assert_eq!(rows["act_trained"], true, "{rows}");
}
