//! End-to-end tests of the `dexjoco-data` binary: exit codes, help, doctor, render.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;
use common::convert_input;

fn bin() -> Command {
    common::dexjoco()
}

fn run(args: &[&str], cwd: &Path) -> Output {
    bin()
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("binary runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn probe_scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/render/tests/data/render_probe.xml")
}

#[test]
fn help_shows_examples_and_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let out = run(&["--help"], dir.path());
    assert!(out.status.success());
    let help = text(&out.stdout);
    for needle in [
        "Examples:",
        "augment --replays 10",
        "Exit codes (",
        "doctor",
        "render",
        "--seed",
        "--jobs",
        "--work-dir",
    ] {
        assert!(help.contains(needle), "--help lacks '{needle}':\n{help}");
    }
    let out = run(&["render", "--help"], dir.path());
    assert!(text(&out.stdout).contains("Examples:"));
}

#[test]
fn usage_errors_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    assert_eq!(
        run(&["render", "--no-such-flag"], dir.path()).status.code(),
        Some(2)
    );
    assert_eq!(
        run(&["--jobs", "0", "doctor"], dir.path()).status.code(),
        Some(2)
    );
}

#[test]
fn flags_refuse_what_the_tools_below_them_refuse_before_any_work() {
    // Issue #44: each value was accepted and failed (or panicked, or aborted) later.
    let dir = tempfile::tempdir().unwrap();
    let demo = dexjoco_testkit::workspace_root().join("datasets/demos/click_mouse/episode_000000");
    let demo = demo.to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["augment", demo, "--keyframe-interval", "4294967295"],
            "--keyframe-interval",
        ),
        (&["augment", demo, "--size", "8194"], "--size"),
        (
            &["augment", demo, "--first-frame-timeout", "1e300"],
            "--first-frame-timeout",
        ),
        (&["render", "--size", "100000"], "--size"),
        (&["render", "--width", "9000"], "--width"),
        (&["render", "--video", "--fps", "4294967295"], "--fps"),
        (&["bench", "render", "--size", "9000"], "--size"),
        (
            &["eval", "--task", "hammer_nail", "--deadline", "1e300"],
            "--deadline",
        ),
        (
            &["eval", "--task", "hammer_nail", "--server-wait", "1e300"],
            "--server-wait",
        ),
        (
            &[
                "eval",
                "--task",
                "hammer_nail",
                "--render-size",
                "100000x100000",
            ],
            "--render-size",
        ),
        (
            &["eval", "--task", "hammer_nail", "--episodes", "100001"],
            "--episodes",
        ),
    ];
    for (args, flag) in cases {
        let out = run(args, dir.path());
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(flag), "{args:?}: {err}");
        assert!(
            !dir.path().join("dexjoco-work").exists(),
            "{args:?} wrote something"
        );
    }
    // The largest keyframe interval accepted is one x264 takes.
    let out = run(
        &[
            "augment",
            demo,
            "--replays",
            "1",
            "--size",
            "32",
            "--quality",
            "fast",
            "--max-frames",
            "6",
            "--keep-failed",
            "--keyframe-interval",
            "2147483647",
        ],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(3), "{}", text(&out.stderr));
    assert!(
        dir.path()
            .join("dexjoco-work/augment/click_mouse/episode_000000__r00/videos/third_person.mp4")
            .is_file(),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn doctor_reports_mujoco_egl_and_ffmpeg() {
    let dir = tempfile::tempdir().unwrap();
    let out = run(&["doctor", "--json"], dir.path());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["mujoco"]["version"], "3.17.0");
    assert!(
        report["mujoco"]["library"]
            .as_str()
            .unwrap()
            .contains("libmujoco.so"),
        "{report}"
    );
    let egl = &report["egl"]["Ok"];
    let selected = egl["selected"].as_u64().expect("an EGL device is selected") as usize;
    let device = &egl["devices"][selected];
    assert!(device["gl_renderer"].is_string(), "{device}");
    assert!(device["software"].is_boolean());
    let encoders = report["ffmpeg"]["encoders"]
        .as_array()
        .expect("ffmpeg found");
    assert!(
        encoders.iter().any(|e| e[0] == "libx264" && e[1] == true),
        "{encoders:?}"
    );

    let human = run(&["doctor"], dir.path());
    let human = text(&human.stdout);
    assert!(
        human.contains("3.17.0") && human.contains("[used]") && human.contains("libx264"),
        "{human}"
    );
}

#[test]
fn render_writes_pngs_of_every_camera_and_a_contact_sheet() {
    let dir = tempfile::tempdir().unwrap();
    let scene = probe_scene();
    let out = run(
        &[
            "render",
            scene.to_str().unwrap(),
            "--width",
            "64",
            "--height",
            "48",
            "--quality",
            "fast",
            "--depth",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let render = dir.path().join("dexjoco-work/render");
    for f in [
        "render_probe_top.png",
        "render_probe_side.png",
        "render_probe_contact_sheet.png",
        "render_probe_top_depth.png",
    ] {
        assert!(render.join(f).is_file(), "{f} missing");
    }
    let top = image::open(render.join("render_probe_top.png"))
        .unwrap()
        .to_rgb8();
    assert_eq!(top.dimensions(), (64, 48));
    let c = top.get_pixel(32, 24);
    assert!(c[0] > 150 && c[1] < 60, "{c:?}");
    // Reported depth range covers the red box's top at 1.3 m.
    assert!(
        text(&out.stdout).contains("depth 1.30"),
        "{}",
        text(&out.stdout)
    );
}

#[test]
fn render_one_camera_to_a_chosen_folder() {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("pics");
    let scene = probe_scene();
    let out = run(
        &[
            "render",
            scene.to_str().unwrap(),
            "--camera",
            "side",
            "--size",
            "32",
            "--out",
            out_dir.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(out_dir.join("render_probe_side.png").is_file());
    assert!(!out_dir.join("render_probe_top.png").exists());
    assert!(!out_dir.join("render_probe_contact_sheet.png").exists());
}

#[test]
fn render_the_builtin_scene_by_default() {
    let dir = tempfile::tempdir().unwrap();
    let out = run(
        &[
            "render",
            "--size",
            "48",
            "--quality",
            "fast",
            "--steps",
            "20",
            "-q",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        dir.path()
            .join("dexjoco-work/render/tabletop_front.png")
            .is_file()
    );
    assert!(
        dir.path()
            .join("dexjoco-work/render/tabletop_contact_sheet.png")
            .is_file()
    );
}

#[test]
fn bad_scene_paths_and_cameras_fail_with_exit_1_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    let out = run(&["render", "nowhere/scene.xml"], dir.path());
    assert_eq!(out.status.code(), Some(1));
    assert!(
        text(&out.stderr).contains("nowhere/scene.xml"),
        "{}",
        text(&out.stderr)
    );

    let scene = probe_scene();
    let out = run(
        &["render", scene.to_str().unwrap(), "--camera", "ceiling"],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(
        err.contains("'ceiling'") && err.contains("top, side"),
        "{err}"
    );
}

#[test]
fn reference_scenes_render_through_the_cli() {
    let dir = tempfile::tempdir().unwrap();
    let xml = dexjoco_testkit::upstream_dir().join("xmls/arena_arm_hand_monitor_mouse.xml");
    let out = run(
        &[
            "render",
            xml.to_str().unwrap(),
            "--camera",
            "front",
            "--size",
            "64",
            "--quality",
            "fast",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        dir.path()
            .join("dexjoco-work/render/arena_arm_hand_monitor_mouse_front.png")
            .is_file()
    );
}

#[test]
fn bench_augment_compares_processes_with_the_reference_and_the_render_only_limit() {
    let dir = tempfile::tempdir().unwrap();
    let demo = dexjoco_testkit::workspace_root().join("datasets/demos/click_mouse/episode_000000");
    let out = run(
        &[
            "-j",
            "2",
            "bench",
            "augment",
            demo.to_str().unwrap(),
            "--size",
            "32",
            "--quality",
            "fast",
            "--replays",
            "2",
            "--max-frames",
            "4",
            "--limit-frames",
            "20",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    for row in [
        "| 32x32 | fast | full | reference (re-simulate every replay, 1 process) | 1 |",
        "| 32x32 | fast | full | ours, worker processes | 1 |",
        "| 32x32 | fast | full | ours, worker processes | 2 |",
        "| 32x32 | fast | full | render-only limit (trajectory states, no stepping, no encoding) | 1 |",
        "| 32x32 | fast | full | render-only limit (trajectory states, no stepping, no encoding) | 2 |",
        "Where a frame's time goes",
        "| physics | scene update | render | readback | encode (x264 CPU) | encoder feed | bottleneck |",
    ] {
        assert!(table.contains(row), "{row} missing:\n{table}");
    }
    let json: serde_json::Value = serde_json::from_str(
        &fs_err::read_to_string(dir.path().join("dexjoco-work/bench/augment.json")).unwrap(),
    )
    .unwrap();
    let runs = json["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 5);
    for r in &runs[..3] {
        assert_eq!(r["frames"], 8, "2 replays x 4 frames: {r}");
        assert!(r["frames_per_s"].as_f64().unwrap() > 0.0);
        assert!(r["of_limit"].as_f64().unwrap() > 0.0);
    }
    assert_eq!(runs[0]["vs_reference"], 1.0);
    assert_eq!(runs[1]["vs_one_worker"], 1.0);
    // Where each augment run's time went: every frame counted, each stage measured.
    for r in &runs[..3] {
        let t = &r["times"];
        assert_eq!(t["frames"], 8, "{r}");
        for stage in ["physics", "render", "readback", "encode_cpu"] {
            assert!(t[stage].as_f64().unwrap() > 0.0, "{stage}: {r}");
        }
    }
    assert!(runs[4]["frames_per_s"].as_f64().unwrap() > 0.0);
}

#[test]
fn bench_render_prints_a_table() {
    let dir = tempfile::tempdir().unwrap();
    let scene = probe_scene();
    let out = run(
        &[
            "bench",
            "render",
            "--scene",
            scene.to_str().unwrap(),
            "--frames",
            "2",
            "--sizes",
            "32",
            "--presets",
            "fast,paper",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    assert!(
        table.contains("| render_probe | 32x32 | fast |")
            && table.contains("| render_probe | 32x32 | paper |"),
        "{table}"
    );
    let json: serde_json::Value = serde_json::from_str(
        &fs_err::read_to_string(dir.path().join("dexjoco-work/bench/render.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(json["rows"].as_array().unwrap().len(), 2);
    assert!(json["rows"][0]["fps"].as_f64().unwrap() > 0.0);
}

#[test]
fn render_video_streams_an_h264_clip_per_camera() {
    let dir = tempfile::tempdir().unwrap();
    let out = run(
        &[
            "render",
            "--video",
            "--steps",
            "100",
            "--size",
            "64",
            "--quality",
            "fast",
            "--camera",
            "front",
            "--camera",
            "top0",
            "-q",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    for cam in ["front", "top0"] {
        let path = dir
            .path()
            .join(format!("dexjoco-work/render/tabletop_{cam}.mp4"));
        let info = dexjoco_video::probe(&path).unwrap();
        // 100 steps of 2 ms = 0.2 s at 30 fps: frames at t = 0, 1/30, ..., 6/30.
        assert_eq!(
            (info.codec.as_str(), info.frames, info.width),
            ("h264", 7, 64),
            "{cam}: {info:?}"
        );
    }
}

#[test]
fn convert_without_input_says_what_to_pass_with_exit_1() {
    let dir = tempfile::tempdir().unwrap();
    let out = run(&["convert"], dir.path());
    assert_eq!(out.status.code(), Some(1));
    let err = text(&out.stderr);
    assert!(
        err.contains("no input") && err.contains("augment") && err.contains("--input"),
        "{err}"
    );
    let help = run(&["convert", "--help"], dir.path());
    let help = text(&help.stdout);
    assert!(
        help.contains("Examples:") && help.contains("--overwrite") && help.contains("lerobot-v3"),
        "{help}"
    );
}

#[test]
fn convert_writes_lerobot_v3_and_refuses_to_overwrite() {
    let dir = tempfile::tempdir().unwrap();
    let input = convert_input(dir.path());
    let args = [
        "convert",
        "--input",
        input.to_str().unwrap(),
        "--out",
        "ds",
        "-q",
    ];
    let out = run(&args, dir.path());
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).contains("2 episodes, 13 frames"),
        "{}",
        text(&out.stdout)
    );
    let info: serde_json::Value = serde_json::from_str(
        &fs_err::read_to_string(dir.path().join("ds/meta/info.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(info["total_frames"], 13);
    assert_eq!(info["robot_type"], "panda_allegro");
    assert!(
        dir.path()
            .join("ds/videos/observation.images.front/chunk-000/file-000.mp4")
            .is_file()
    );

    let again = run(&args, dir.path());
    assert_eq!(again.status.code(), Some(1));
    assert!(
        text(&again.stderr).contains("--overwrite"),
        "{}",
        text(&again.stderr)
    );
    let mut over = args.to_vec();
    over.extend(["--overwrite", "--exclude", "episode_000001"]);
    let out = run(&over, dir.path());
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).contains("1 episodes")
            && text(&out.stdout).contains("left out: episode_000001")
    );

    // A broken episode is left out and named; the other is written; exit code 3.
    let broken = input.join("click_mouse/episode_000000");
    fs_err::remove_file(broken.join("videos/front.mp4")).unwrap();
    let mut over = args.to_vec();
    over.push("--overwrite");
    let out = run(&over, dir.path());
    let stdout = text(&out.stdout);
    assert_eq!(out.status.code(), Some(3), "{stdout}{}", text(&out.stderr));
    assert!(stdout.contains("1 episodes, 7 frames"), "{stdout}");
    assert!(
        stdout.contains("1 episode(s) could not be converted")
            && stdout.contains("episode_000000")
            && stdout.contains("front"),
        "{stdout}"
    );
}

#[test]
fn convert_writes_diffusion_policy_v21_and_norm_stats() {
    let dir = tempfile::tempdir().unwrap();
    let input = convert_input(dir.path());
    let input = input.to_str().unwrap();
    let out = run(
        &[
            "convert",
            "--input",
            input,
            "--out",
            "dp",
            "--format",
            "diffusion-policy",
            "--videos",
            "--norm-stats",
            "--norm-stats-batch",
            "4",
            "-q",
        ],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    let dp = dir.path().join("dp");
    assert!(
        dp.join("replay_buffer.zarr/meta/episode_ends/.zarray")
            .is_file()
    );
    assert!(dp.join("videos/1/0.mp4").is_file());
    let norm: serde_json::Value =
        serde_json::from_str(&fs_err::read_to_string(dp.join("norm_stats.json")).unwrap()).unwrap();
    assert_eq!(
        norm["norm_stats"]["actions"]["q99"]
            .as_array()
            .unwrap()
            .len(),
        22
    );
    assert_eq!(
        norm["norm_stats"]["state"]["mean"]
            .as_array()
            .unwrap()
            .len(),
        23
    );

    let out = run(
        &[
            "convert",
            "--input",
            input,
            "--out",
            "v21",
            "--format",
            "lerobot-v2.1",
            "-q",
        ],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
    assert!(dir.path().join("v21/meta/episodes_stats.jsonl").is_file());

    // --videos belongs to the Diffusion Policy format: a usage error.
    let out = run(
        &["convert", "--input", input, "--out", "x", "--videos"],
        dir.path(),
    );
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
}

#[test]
fn render_task_uses_the_specs_built_in_outside_the_checkout() {
    // The working folder is a temporary one: no schemas/tasks beside it.
    let dir = tempfile::tempdir().unwrap();
    let out = run(
        &[
            "-q",
            "render",
            "--task",
            "click_mouse",
            "--camera",
            "front",
            "--size",
            "32",
            "--quality",
            "fast",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let png = dir
        .path()
        .join("dexjoco-work/render/click_mouse_builtin_front.png");
    let img = image::open(&png).unwrap().to_rgb8();
    assert_eq!(img.dimensions(), (32, 32));

    let out = run(&["render", "--task", "no_such_task"], dir.path());
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(
        err.contains("unknown task 'no_such_task'") && err.contains("click_mouse"),
        "{err}"
    );

    // --tasks-dir adds to the built-in specs; a broken file there is named.
    let specs = dir.path().join("specs");
    fs_err::create_dir(&specs).unwrap();
    fs_err::write(specs.join("my_task.toml"), "id = \"my_task\"\nbogus = 1\n").unwrap();
    let out = run(
        &[
            "render",
            "--task",
            "click_mouse",
            "--tasks-dir",
            specs.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(err.contains("my_task.toml"), "{err}");
}

#[test]
fn cameras_writes_a_pool_that_augment_uses() {
    let dir = tempfile::tempdir().unwrap();
    let pool = dir.path().join("pool.json");
    let out = run(
        &[
            "cameras",
            "--task",
            "click_mouse",
            "--count",
            "10",
            "--candidates",
            "200",
            "--out",
            pool.to_str().unwrap(),
            "--preview",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert!(stdout.contains("10 of 200 poses kept"), "{stdout}");
    assert!(dir.path().join("pool_preview.png").is_file());
    let json: serde_json::Value =
        serde_json::from_str(&fs_err::read_to_string(&pool).unwrap()).unwrap();
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 10);
    assert!(rows.iter().all(|r| r[2] == 1.4 && r[3] == 45.0));

    let demo = dexjoco_testkit::workspace_root().join("datasets/demos/click_mouse/episode_000000");
    let aug = dir.path().join("aug");
    let out = run(
        &[
            "-q",
            "augment",
            demo.to_str().unwrap(),
            "--camera-pool",
            pool.to_str().unwrap(),
            "--replays",
            "1",
            "--max-frames",
            "3",
            "--size",
            "32",
            "--keep-failed",
            "--out",
            aug.to_str().unwrap(),
        ],
        dir.path(),
    );
    // The first 3 frames do not reach success: exit 3 (partial), replay kept.
    assert_eq!(out.status.code(), Some(3), "{}", text(&out.stderr));
    let report: serde_json::Value =
        serde_json::from_str(&fs_err::read_to_string(aug.join("augment_report.json")).unwrap())
            .unwrap();
    assert_eq!(
        report["camera_pools"]["click_mouse"].as_str().unwrap(),
        pool.to_str().unwrap()
    );
    let cam = &report["replays"][0]["sample"]["camera"];
    assert!(
        rows.iter()
            .any(|r| r[0] == cam["azimuth"] && r[1] == cam["elevation"]),
        "{cam} is not from the pool"
    );

    // An unknown task is a usage error naming it.
    let out = run(&["cameras", "--task", "no_such_task"], dir.path());
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("no_such_task"));
}
