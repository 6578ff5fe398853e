//! The augment stage on the sample demos with the built-in scenes: replays
//! match the recording, outputs do not depend on the worker count, rendering from one
//! simulation equals re-simulating every replay, and the report says what was sampled.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use dexjoco_augment::{AugmentConfig, AugmentRun, augment};
use dexjoco_core::NoProgress;
use dexjoco_render::RenderSettings;
use dexjoco_sim::SceneSource;

fn demos() -> PathBuf {
    dexjoco_testkit::workspace_root().join("datasets/demos")
}

fn config(inputs: Vec<PathBuf>, out: &Path) -> AugmentConfig {
    AugmentConfig {
        replays: 2,
        seed: 7,
        settings: RenderSettings {
            width: 64,
            height: 64,
            ..RenderSettings::default()
        },
        keep_failed: true,
        max_frames: Some(8),
        contact_sheet: false,
        ..AugmentConfig::new(inputs, out)
    }
}

fn run(c: &AugmentConfig, threads: usize) -> AugmentRun {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| augment(c, &NoProgress))
        .unwrap()
}

/// Every file under `dir` (relative path -> bytes), reports left out.
fn tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut m = dexjoco_testkit::file_tree(dir);
    m.retain(|rel, _| !rel.starts_with("augment_report"));
    m
}

#[test]
fn every_sample_demo_replays_to_success_with_zero_deviation() {
    // Physics only (no replay rendered), whole episodes.
    let out = tempfile::tempdir().unwrap();
    let mut c = config(vec![demos()], out.path());
    c.replays = 0;
    c.max_frames = None;
    let report = run(&c, 2);
    // One scripted demonstration per planned task, two of click_mouse.
    assert_eq!(
        report.episodes.len(),
        dexjoco_scripted::PLANNED_TASKS.len() + 1
    );
    for e in &report.episodes {
        assert!(
            e.success,
            "{}/{} did not replay to success",
            e.task, e.episode
        );
        assert_eq!(
            e.max_state_deviation, 0.0,
            "{}/{}: replayed state differs from the recording",
            e.task, e.episode
        );
        assert!(e.steps > 100);
        // Segmented into every subtask of its task, in order, the last one ending on
        // the success step.
        let spec = dexjoco_core::TaskSpec::builtin(&e.task).unwrap();
        let ids: Vec<&str> = e.subtasks.iter().map(|s| s.id.as_str()).collect();
        let want: Vec<&str> = spec.subtasks.iter().map(|s| s.id.as_str()).collect();
        assert_eq!(ids, want, "{}/{}", e.task, e.episode);
        assert!(
            e.subtasks
                .iter()
                .all(|s| s.start.is_some_and(|a| s.end.is_some_and(|b| a <= b))),
            "{}/{}: {:?}",
            e.task,
            e.episode,
            e.subtasks
        );
        assert_eq!(e.subtasks.last().unwrap().end, e.first_success);
    }
}

#[test]
fn output_is_identical_whatever_the_thread_count_and_equals_resimulation() {
    let input = demos().join("click_mouse/episode_000000");
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    let r = tempfile::tempdir().unwrap();
    let ra = run(&config(vec![input.clone()], a.path()), 1);
    let rb = run(&config(vec![input.clone()], b.path()), 2);
    let mut resim = config(vec![input], r.path());
    resim.resimulate_per_replay = true;
    let rr = run(&resim, 2);

    assert_eq!(ra.replays.len(), 2);
    assert_eq!(ra.replays, rb.replays);
    assert_eq!(ra.replays, rr.replays);
    let (ta, tb, tr) = (tree(a.path()), tree(b.path()), tree(r.path()));
    assert!(ta.keys().any(|k| k.ends_with("third_person.mp4")));
    assert!(ta.keys().any(|k| k.contains("replay.zarr/data/state")));
    assert_eq!(ta, tb, "1 vs 2 worker threads");
    assert_eq!(ta, tr, "one simulation per episode vs one per replay");

    // The two replays differ (different seeds, camera, lights), so the comparison above
    // would notice a mix-up, and the decoded frames are the rendered ones.
    let v0 = a
        .path()
        .join("click_mouse/episode_000000__r00/videos/third_person.mp4");
    let v1 = a
        .path()
        .join("click_mouse/episode_000000__r01/videos/third_person.mp4");
    let f0 = dexjoco_video::decode_rgb(&v0).unwrap();
    let f1 = dexjoco_video::decode_rgb(&v1).unwrap();
    assert_eq!(f0.len(), 8);
    assert_ne!(f0, f1);
    assert_ne!(ra.replays[0].sample.seed, ra.replays[1].sample.seed);
}

#[test]
fn replays_read_back_as_raw_episodes_with_the_recorded_actions() {
    let input = demos().join("click_mouse/episode_000001");
    let out = tempfile::tempdir().unwrap();
    let mut c = config(vec![input.clone()], out.path());
    c.replays = 1;
    c.contact_sheet = true;
    let report = run(&c, 1);
    let dir = out.path().join("click_mouse/episode_000001__r00");
    let ep = read_stored_episode(&dir).unwrap();
    let src = read_stored_episode(&input).unwrap();
    assert_eq!(ep.len(), 8);
    let (a, s) = (ep.array("action").unwrap(), src.array("action").unwrap());
    for k in 0..8 {
        assert_eq!(a.row(k), s.row(k));
        assert_eq!(
            ep.array("state").unwrap().row(k),
            src.array("state").unwrap().row(k)
        );
    }
    assert!(ep.array("action_rotvec").is_some());
    let info = dexjoco_video::probe(&dir.join("videos/third_person.mp4")).unwrap();
    assert_eq!((info.width, info.height), (64, 64));
    assert!(out.path().join("contact_sheet.png").is_file());
    assert!(out.path().join("augment_report.md").is_file());
    // The built-in scene's texture library: table_ceramic and 19 procedural textures,
    // all of them materials of the model (no colour-only fallback).
    let lib = &report.table_library["click_mouse"];
    assert_eq!(lib.len(), 20, "{lib:?}");
    assert!(lib.iter().any(|n| n == "table_ceramic"), "{lib:?}");
    assert_eq!(
        lib.iter().filter(|n| n.starts_with("table_tex_")).count(),
        19
    );
    assert!(
        report.camera_pools["click_mouse"].contains("built-in single-arm"),
        "{:?}",
        report.camera_pools
    );
}

#[test]
fn depth_streams_to_npz_that_numpy_loads_and_equals_a_direct_render() {
    let tmp = tempfile::tempdir().unwrap();
    let inputs = vec![demos().join("click_mouse/episode_000000")];
    let mut c = config(inputs, tmp.path());
    c.replays = 1;
    c.max_frames = Some(6);
    c.cameras = vec!["front".into()];
    c.depth = true;
    let report = run(&c, 1);
    let rec = &report.replays[0];
    assert_eq!(
        rec.depth,
        ["videos/third_person_depth.npz", "videos/front_depth.npz"]
    );
    let dir = tmp.path().join("click_mouse").join(&rec.name);
    let npz = dir.join("videos/front_depth.npz");
    let got = dexjoco_testkit::run_python_json("read_depth_npz.py", &[npz.to_str().unwrap()]);
    assert_eq!(got["members"], serde_json::json!(["depth"]));
    assert_eq!(got["dtype"], "float32");
    assert_eq!(got["shape"], serde_json::json!([6, 64, 64]));
    // Metres: the front camera at (1.3, 0, 1.6) sees the table and robot within a few metres.
    let (lo, hi) = (got["min"].as_f64().unwrap(), got["max"].as_f64().unwrap());
    assert!(lo > 0.2 && hi < 20.0 && lo < hi, "depth range {lo}..{hi}");

    // The archive equals the depth of the same frames rendered directly.
    let ((t, h, w), values) = dexjoco_formats::npz::read_depth_npz(&npz).unwrap();
    assert_eq!((t, h, w), (6, 64, 64));
    assert_eq!(
        got["centre_last"].as_f64().unwrap() as f32,
        values[5 * 64 * 64 + 32 * 64 + 32]
    );
    let spec = dexjoco_core::TaskSpec::builtin("click_mouse").unwrap();
    let scene = dexjoco_sim::load_task_scene(&SceneSource::BuiltIn, spec).unwrap();
    let ep = read_stored_episode(&demos().join("click_mouse/episode_000000")).unwrap();
    let state0 = ep
        .array(dexjoco_core::Episode::STATE)
        .unwrap()
        .row(0)
        .to_vec();
    let mut env = dexjoco_sim::TaskEnv::from_initial_state(
        &scene,
        spec,
        &state0,
        dexjoco_sim::EnvOptions::default(),
    )
    .unwrap();
    let mut r = dexjoco_render::Renderer::new(
        &scene.model,
        RenderSettings {
            depth: true,
            ..c.settings
        },
    )
    .unwrap();
    let cam = scene.camera_id("front").unwrap();
    let actions = ep.array(dexjoco_core::Episode::ACTION).unwrap();
    for k in 0..6 {
        let f = r
            .render(env.data_mut(), dexjoco_render::CameraView::Fixed(cam))
            .unwrap();
        let d = f.depth.unwrap();
        assert_eq!(&values[k * 64 * 64..(k + 1) * 64 * 64], &d[..], "frame {k}");
        env.step(actions.row(k)).unwrap();
    }
    // The raw reader attaches the depth stream to its camera.
    let replay = read_stored_episode(&dir).unwrap();
    let front = replay.cameras.iter().find(|c| c.name == "front").unwrap();
    assert_eq!(
        front.depth.as_deref(),
        Some(Path::new("videos/front_depth.npz"))
    );
}

/// A recording the DexJoCo reference code made on its scene (its replay script's writer,
/// through `tests/python/dexjoco_reference.py record`, of a click_mouse demonstration's
/// actions), under `<dir>/click_mouse/`, augmented with `--scene-dir` pointing at the
/// reference scenes (and so the reference camera pool and table textures).
#[test]
fn a_recording_the_reference_code_made_replays_to_success_with_scene_dir() {
    let xmls = dexjoco_testkit::reference_scene_dir();
    let spec = dexjoco_core::TaskSpec::builtin("click_mouse").unwrap();
    let source = SceneSource::Dir(xmls.clone());
    let scene = dexjoco_sim::load_task_scene(&source, spec).unwrap();
    let mut x = 0x9e37_79b9_7f4a_7c15_u64;
    let mut uniform = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    let s0 = dexjoco_sim::TaskEnv::sample_initial_state(&scene, spec, &mut uniform).unwrap();
    let ep = dexjoco_scripted::click_mouse_demo(&scene, spec, &s0, "episode_000000").unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let planned = tmp.path().join("planned/click_mouse/episode_000000");
    dexjoco_formats::raw::write_replay_zarr(&planned, &ep).unwrap();
    let recorded = tmp.path().join("recorded/click_mouse");
    let stdout = dexjoco_testkit::run_reference_python(
        "dexjoco_reference.py",
        &[
            "record",
            "--task",
            "click_mouse",
            "--episode",
            planned.to_str().unwrap(),
            "--out",
            recorded.to_str().unwrap(),
        ],
    );
    let made: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
    // The mouse click is contact: the last bits of the arithmetic (the reference's, pinned
    // by the harness, and ours) move the success step by a step or two, within the
    // extension augment gives every replay (docs/reference-parity.md measures it).
    let extend = dexjoco_augment::DEFAULT_EXTEND_STEPS;
    let planned = ep.len() - 1;
    let recorded = made["first_success"]
        .as_u64()
        .unwrap_or_else(|| panic!("the reference's replay of our plan did not succeed: {made}"))
        as usize;
    eprintln!(
        "our plan succeeds at {planned}, the reference's recording of it at {recorded} ({})",
        made["arithmetic"]
    );
    assert!(recorded.abs_diff(planned) <= extend, "{made}");

    let out = tmp.path().join("aug");
    let mut c = config(vec![tmp.path().join("recorded")], &out);
    c.scene = source;
    c.replays = 2;
    c.max_frames = None;
    c.keep_failed = false;
    let report = run(&c, 2);
    let e = &report.episodes[0];
    assert!(e.success, "{e:?}");
    let replayed = e.first_success.expect("a success step");
    eprintln!("our replay of the reference's recording succeeds at {replayed}");
    assert!(replayed.abs_diff(recorded) <= extend, "{e:?}");
    // Equal to rounding until the mouse is touched, then as far apart as the reference
    // is from itself under a 1e-9 m nudge (2.4e-2 here: docs/reference-parity.md).
    assert!(e.max_state_deviation < 0.05, "{e:?}");
    assert_eq!(report.replays.len(), 2);
    let pool = &report.camera_pools["click_mouse"];
    assert!(pool.ends_with("replay_cameras.json"), "{pool}");
    // The table looks come from the reference texture library, not the built-in one.
    let looks = &report.table_library["click_mouse"];
    assert!(
        looks.len() > 1 && looks.iter().all(|l| !l.starts_with("table_tex_")),
        "{looks:?}"
    );
}

#[test]
fn dynamics_are_drawn_in_the_spec_ranges_per_replay_and_change_the_physics() {
    use dexjoco_core::DynamicsRandomization as D;
    let spec = dexjoco_core::TaskSpec::builtin("click_mouse").unwrap();
    assert!(!spec.dynamics.is_empty());
    let scene = dexjoco_sim::load_task_scene(&SceneSource::BuiltIn, spec).unwrap();
    let original = dexjoco_augment::read_dynamics(spec, &scene.model).unwrap();
    let ranges: Vec<(bool, [f64; 2])> = spec
        .dynamics
        .iter()
        .map(|d| match d {
            D::FrictionlossUniform { range, .. } => (false, *range),
            D::MassScale { range, .. }
            | D::FrictionlossScale { range, .. }
            | D::StiffnessScale { range, .. } => (true, *range),
        })
        .collect();
    let mut draws = Vec::new();
    for seed in 0..20 {
        let v = dexjoco_augment::sample_dynamics(spec, &scene.model, seed).unwrap();
        for ((d, &(scale, r)), o) in v.iter().zip(&ranges).zip(&original) {
            assert_eq!(d.original, *o);
            let (lo, hi) = if scale {
                (o * r[0], o * r[1])
            } else {
                (r[0], r[1])
            };
            assert!(d.value >= lo && d.value <= hi, "{d:?} outside [{lo}, {hi}]");
        }
        let m = dexjoco_augment::apply_dynamics(spec, &scene.model, &v).unwrap();
        let applied = dexjoco_augment::read_dynamics(spec, &m).unwrap();
        assert_eq!(applied, v.iter().map(|d| d.value).collect::<Vec<_>>());
        draws.push(v);
    }
    // The scene's model is untouched, and the draws differ.
    assert_eq!(
        dexjoco_augment::read_dynamics(spec, &scene.model).unwrap(),
        original
    );
    assert!(draws.windows(2).all(|w| w[0] != w[1]));

    // Whole click_mouse episodes (the hand pushes the mouse, whose mass is drawn).
    let tmp = tempfile::tempdir().unwrap();
    let inputs = vec![demos().join("click_mouse/episode_000000")];
    let mut c = config(inputs.clone(), &tmp.path().join("dyn1"));
    c.settings.width = 32;
    c.settings.height = 32;
    c.max_frames = None;
    c.dynamics = true;
    let one = run(&c, 1);
    assert_eq!(one.replays.len(), 2, "keep_failed keeps both");
    for r in &one.replays {
        let v = r.dynamics.as_ref().expect("drawn values in the report");
        assert_eq!(v.len(), spec.dynamics.len());
    }
    assert_ne!(one.replays[0].dynamics, one.replays[1].dynamics);
    assert!(
        one.replays.iter().any(|r| r.max_state_deviation > 0.0),
        "randomized masses left the physics unchanged: {:?}",
        one.replays
            .iter()
            .map(|r| (r.max_state_deviation, r.success))
            .collect::<Vec<_>>()
    );
    // The state written is the replay's own simulation.
    let rec = &one.replays[0];
    let ep = read_stored_episode(&tmp.path().join("dyn1/click_mouse").join(&rec.name)).unwrap();
    let src = read_stored_episode(&inputs[0]).unwrap();
    let (a, b) = (
        ep.array(dexjoco_core::Episode::STATE).unwrap(),
        src.array(dexjoco_core::Episode::STATE).unwrap(),
    );
    let dev = a
        .as_slice()
        .iter()
        .zip(b.as_slice())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert_eq!(dev, rec.max_state_deviation);

    // Same seed, two workers: the same bytes.
    c.out = tmp.path().join("dyn2");
    let two = run(&c, 2);
    assert_eq!(
        tree(&tmp.path().join("dyn1")),
        tree(&tmp.path().join("dyn2"))
    );
    assert_eq!(one.replays, two.replays);

    // The visual draw of a replay does not depend on --dynamics.
    c.out = tmp.path().join("plain");
    c.dynamics = false;
    c.max_frames = Some(4);
    let plain = run(&c, 2);
    for (a, b) in plain.replays.iter().zip(&one.replays) {
        assert_eq!(a.sample, b.sample);
        assert!(a.dynamics.is_none());
    }
}

/// Copies the folder `src` to `dst` (parents made), as `cp -r` does.
fn copy_dir(src: &Path, dst: &Path) {
    fs_err::create_dir_all(dst.parent().unwrap()).unwrap();
    let status = std::process::Command::new("cp")
        .args(["-r", src.to_str().unwrap(), dst.to_str().unwrap()])
        .status()
        .unwrap();
    assert!(status.success());
}

#[test]
fn a_bad_input_is_skipped_and_named_while_the_rest_is_replayed() {
    let tmp = tempfile::tempdir().unwrap();
    // A raw folder whose action array is gone, and a file that is not MCAP.
    let broken = tmp.path().join("click_mouse/episode_000007");
    let src = demos().join("click_mouse/episode_000000");
    copy_dir(&src, &broken);
    fs_err::remove_dir_all(broken.join("replay.zarr/data/action")).unwrap();
    let junk = tmp.path().join("junk.mcap");
    fs_err::write(&junk, b"not an mcap").unwrap();
    // A one-arm recording filed under a two-arm task: read, then rejected by the scene.
    let misfiled = tmp.path().join("two/bimanual_unlock_ipad/episode_000009");
    copy_dir(&src, &misfiled);
    let missing = tmp.path().join("no_such_folder");

    let inputs = vec![
        demos().join("click_mouse/episode_000001"),
        broken.parent().unwrap().to_path_buf(),
        junk.clone(),
        missing.clone(),
        misfiled.parent().unwrap().to_path_buf(),
    ];
    let mut c = config(inputs, &tmp.path().join("out"));
    c.replays = 1;
    c.max_frames = Some(3);
    let report = run(&c, 1);
    assert_eq!(report.episodes.len(), 1);
    assert_eq!(report.replays.len(), 1);
    assert_eq!(report.skipped.len(), 4, "{:?}", report.skipped);
    let by_source = |p: &Path| {
        report
            .skipped
            .iter()
            .find(|k| k.source == p.display().to_string())
            .unwrap_or_else(|| panic!("{} not skipped: {:?}", p.display(), report.skipped))
            .reason
            .clone()
    };
    let reason = by_source(&broken);
    assert!(reason.contains("field 'action'"), "{reason}");
    assert!(by_source(&junk).contains("not an MCAP file"));
    assert!(by_source(&missing).contains("no_such_folder"));
    let reason = by_source(&misfiled);
    // Its arrays are a one-arm task's: the checks every door applies name the first
    // (and count the others).
    assert!(
        reason.contains("episode_000009")
            && reason.contains("expected 46 values per frame")
            && reason.contains("more problem"),
        "{reason}"
    );
    let md = fs_err::read_to_string(tmp.path().join("out/augment_report.md")).unwrap();
    assert!(md.contains("Skipped inputs (4)"), "{md}");

    // Nothing replayable at all: an error with the first reason.
    let c = config(vec![junk.clone()], &tmp.path().join("none"));
    let err = augment(&c, &NoProgress).unwrap_err().to_string();
    assert!(
        err.contains("none of the 1 input(s)") && err.contains("junk.mcap"),
        "{err}"
    );
}

#[test]
fn replays_failing_under_their_dynamics_draw_are_recorded_once_and_kept_on_request() {
    // Own specs: the mouse up to 20 times heavier, so some draws fail the task.
    let tmp = tempfile::tempdir().unwrap();
    let specs = tmp.path().join("specs");
    fs_err::create_dir(&specs).unwrap();
    let text = fs_err::read_to_string(
        dexjoco_testkit::workspace_root().join("schemas/tasks/click_mouse.toml"),
    )
    .unwrap();
    assert!(text.contains("range = [0.75, 1.25]"));
    fs_err::write(
        specs.join("click_mouse.toml"),
        text.replace("range = [0.75, 1.25]", "range = [1.0, 20.0]"),
    )
    .unwrap();
    let out = tmp.path().join("out");
    let mut c = config(vec![demos().join("click_mouse/episode_000000")], &out);
    c.tasks_dir = Some(specs);
    c.replays = 4;
    c.settings.width = 32;
    c.settings.height = 32;
    c.max_frames = None;
    c.dynamics = true;
    c.keep_failed = false;
    let first = run(&c, 2);
    assert!(
        !first.replays.is_empty() && !first.dropped.is_empty(),
        "{first:?}"
    );
    assert_eq!(first.replays.len() + first.dropped.len(), 4);
    assert!(first.replays.iter().all(|r| r.success));
    for d in &first.dropped {
        assert!(!d.success && d.videos.is_empty());
        assert!(d.dynamics.as_ref().unwrap()[0].value > d.dynamics.as_ref().unwrap()[0].original);
        assert!(!out.join("click_mouse").join(&d.name).exists());
    }
    let stamp = |name: &str| {
        fs_err::metadata(
            out.join(".dropped/click_mouse")
                .join(format!("{name}.json")),
        )
        .unwrap()
        .modified()
        .unwrap()
    };
    let stamps: Vec<_> = first.dropped.iter().map(|d| stamp(&d.name)).collect();

    // Run again: nothing is simulated or rendered again, and the report is the same.
    let again = run(&c, 2);
    assert_eq!(again.rendered_now, 0);
    assert_eq!(again.dropped, first.dropped);
    assert_eq!(again.replays, first.replays);
    let now: Vec<_> = first.dropped.iter().map(|d| stamp(&d.name)).collect();
    assert_eq!(now, stamps, "a dropped replay was simulated again");

    // Another seed into the same folder is refused, naming the difference.
    let mut other = c.clone();
    other.seed = 8;
    let err = augment(&other, &NoProgress).unwrap_err().to_string();
    assert!(
        err.contains("other settings") && err.contains("seed: 8 (was 7)"),
        "{err}"
    );

    // With --keep-failed the dropped ones are made and kept, flagged, with the same draw.
    c.keep_failed = true;
    let kept = run(&c, 2);
    assert!(kept.dropped.is_empty());
    assert_eq!(kept.replays.len(), 4);
    assert_eq!(kept.rendered_now, first.dropped.len());
    for d in &first.dropped {
        let r = kept.replays.iter().find(|r| r.name == d.name).unwrap();
        assert!(!r.success);
        assert_eq!(r.dynamics, d.dynamics);
        assert_eq!(r.sample, d.sample);
        assert!(
            !out.join(".dropped/click_mouse")
                .join(format!("{}.json", d.name))
                .exists()
        );
    }
}

fn read_stored_episode(dir: &Path) -> dexjoco_formats::Result<dexjoco_core::Episode> {
    dexjoco_formats::read_episode(dir, dexjoco_core::TaskSet::builtin())
}

/// The sample click_mouse demo without its last frame. The recorder stops on the step that
/// first succeeds, so this is a recording whose replay succeeds one step after it ends:
/// what a drift of one step (another MuJoCo version, the controller's rounding) does to a
/// real DexJoCo recording.
fn one_step_short(dir: &Path) -> (PathBuf, usize) {
    let n = read_stored_episode(&demos().join("click_mouse/episode_000000"))
        .unwrap()
        .len();
    (cut_recording(dir, n - 1), n - 1)
}

/// The sample click_mouse demo's first `frames` frames, written as a raw episode in `dir`.
fn cut_recording(dir: &Path, frames: usize) -> PathBuf {
    let mut ep = read_stored_episode(&demos().join("click_mouse/episode_000000")).unwrap();
    for a in ep.arrays.values_mut() {
        let rows: Vec<&[f64]> = (0..frames).map(|k| a.row(k)).collect();
        *a = dexjoco_core::FrameArray::from_rows(&rows).unwrap();
    }
    let folder = dir.join("click_mouse/episode_000000");
    dexjoco_formats::raw::write_replay_zarr(&folder, &ep).unwrap();
    folder
}

#[test]
fn a_replay_that_succeeds_one_step_late_is_kept_by_the_extension_with_its_shift() {
    let tmp = tempfile::tempdir().unwrap();
    // The sample demo itself succeeds exactly on its last frame (shift 0, not extended).
    let mut c = config(
        vec![demos().join("click_mouse/episode_000000")],
        &tmp.path().join("whole"),
    );
    c.max_frames = None;
    c.keep_failed = false;
    c.replays = 1;
    c.settings.width = 32;
    c.settings.height = 32;
    let whole = run(&c, 2);
    let e = &whole.episodes[0];
    assert_eq!(e.first_success, Some(e.recorded_steps - 1));
    assert_eq!((e.success_shift, e.extended), (Some(0), false));

    let (input, recorded) = one_step_short(tmp.path());
    // Strict replay (the reference's): no success within the recording; dropped.
    c.inputs = vec![input.clone()];
    c.out = tmp.path().join("strict");
    c.extend_steps = 0;
    let strict = run(&c, 2);
    assert!(!strict.episodes[0].success);
    assert!(strict.replays.is_empty());

    // With the extension: the last action repeats, the success comes one step later, the
    // replay is kept and the shift reported.
    c.out = tmp.path().join("extended");
    c.extend_steps = 30;
    c.replays = 2;
    let ext = run(&c, 2);
    let e = &ext.episodes[0];
    assert!(e.success && e.extended);
    assert_eq!(e.recorded_steps, recorded);
    assert_eq!(e.first_success, Some(recorded));
    assert_eq!(e.success_shift, Some(1));
    assert_eq!(e.shift_label(), "+1 step, extended");
    assert_eq!(e.steps, recorded + 1);
    assert_eq!(ext.replays.len(), 2);
    let md = fs_err::read_to_string(c.out.join("augment_report.md")).unwrap();
    assert!(md.contains("+1 step, extended"), "{md}");
    let src = read_stored_episode(&input).unwrap();
    for r in &ext.replays {
        assert!(r.extended && r.success);
        assert_eq!((r.steps, r.recorded_steps), (recorded + 1, recorded));
        // The extra frame is written like the others: state, the repeated action, the
        // next timestamp at the episode's rate.
        let ep = read_stored_episode(&c.out.join("click_mouse").join(&r.name)).unwrap();
        assert_eq!(ep.len(), recorded + 1);
        let action = ep.array("action").unwrap();
        assert_eq!(
            action.row(recorded),
            src.array("action").unwrap().row(recorded - 1)
        );
        let ts = ep.array("timestamp").unwrap();
        let step = ts.row(recorded)[0] - ts.row(recorded - 1)[0];
        assert!((step - 1.0 / 30.0).abs() < 1e-9, "{step}");
        assert_eq!(ep.array("state").unwrap().len(), recorded + 1);
    }

    // --dynamics honours it too (a spec whose draw changes nothing: the same late success).
    let specs = tmp.path().join("specs");
    fs_err::create_dir(&specs).unwrap();
    let text = fs_err::read_to_string(
        dexjoco_testkit::workspace_root().join("schemas/tasks/click_mouse.toml"),
    )
    .unwrap();
    fs_err::write(
        specs.join("click_mouse.toml"),
        text.replace("range = [0.75, 1.25]", "range = [1.0, 1.0]"),
    )
    .unwrap();
    c.tasks_dir = Some(specs);
    c.dynamics = true;
    c.out = tmp.path().join("dynamics");
    let dyn_run = run(&c, 2);
    assert!(dyn_run.dropped.is_empty(), "{:?}", dyn_run.dropped);
    assert_eq!(dyn_run.replays.len(), 2);
    for r in &dyn_run.replays {
        assert!(r.extended && r.success);
        assert_eq!(r.first_success, Some(recorded));
    }
}

#[test]
fn a_replay_that_never_succeeds_is_not_flagged_extended() {
    // A recording cut far before its success: the extension runs all its steps without a
    // success; kept with --keep-failed, the replay is a failure, not an extended success.
    let tmp = tempfile::tempdir().unwrap();
    let input = cut_recording(&tmp.path().join("in"), 40);
    let mut c = config(vec![input], &tmp.path().join("out"));
    c.max_frames = None;
    c.keep_failed = true;
    c.replays = 1;
    c.extend_steps = 5;
    c.settings.width = 32;
    c.settings.height = 32;
    let report = run(&c, 1);
    let e = &report.episodes[0];
    assert!(!e.success);
    assert_eq!((e.recorded_steps, e.steps), (40, 45), "the extension ran");
    assert!(!e.extended, "no success, so not extended");
    assert_eq!(report.replays.len(), 1);
    assert!(!report.replays[0].extended && !report.replays[0].success);
    let md = fs_err::read_to_string(c.out.join("augment_report.md")).unwrap();
    assert!(!md.contains("only after the recording ended"), "{md}");
}

#[test]
fn an_output_folder_inside_the_input_folder_is_not_read_as_input() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("data");
    copy_dir(
        &demos().join("click_mouse/episode_000000"),
        &input.join("click_mouse/episode_000000"),
    );
    let mut c = config(vec![input.clone()], &input.join("aug"));
    c.replays = 1;
    c.max_frames = Some(3);
    c.keep_failed = true;
    c.extend_steps = 0;
    c.settings.width = 32;
    c.settings.height = 32;
    let first = run(&c, 1);
    assert_eq!(first.episodes.len(), 1);
    // The second run (a resume) finds its own replays under the input folder and leaves
    // them out: still one episode, nothing rendered.
    let again = run(&c, 1);
    assert_eq!(again.episodes.len(), 1, "{:?}", again.episodes);
    assert!(again.skipped.is_empty(), "{:?}", again.skipped);
    assert_eq!(again.rendered_now, 0);
}
