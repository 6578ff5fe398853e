//! End-to-end checks of the smaller fixes of issue #24: flags that were ignored or meant
//! different things in different commands, hints and causes printed wrong, exit codes.

use std::path::Path;
use std::process::Output;

mod common;

fn run(args: &[&str], cwd: &Path) -> Output {
    common::dexjoco()
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("binary runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// The first still `render` printed (its path on stdout).
fn first_png(out: &Output) -> std::path::PathBuf {
    text(&out.stdout)
        .lines()
        .next()
        .expect("render printed a path")
        .into()
}

#[test]
fn render_task_applies_depth_and_steps_and_refuses_video_and_fps() {
    let dir = tempfile::tempdir().unwrap();
    let render = |extra: &[&str], out: &str| {
        let mut args = vec![
            "render",
            "--task",
            "click_mouse",
            "--size",
            "32",
            "--quality",
            "fast",
            "--out",
            out,
        ];
        args.extend_from_slice(extra);
        run(&args, dir.path())
    };
    let at_reset = render(&["--depth"], "reset");
    assert!(at_reset.status.success(), "{}", text(&at_reset.stderr));
    let png = dir.path().join(first_png(&at_reset));
    let depth = png.with_file_name(format!(
        "{}_depth.png",
        png.file_stem().unwrap().to_str().unwrap()
    ));
    assert!(
        depth.is_file(),
        "--depth wrote no {}: {}",
        depth.display(),
        text(&at_reset.stdout)
    );
    let stepped = render(&["--steps", "300"], "stepped");
    assert!(stepped.status.success(), "{}", text(&stepped.stderr));
    let (a, b) = (
        image::open(&png).unwrap().to_rgb8(),
        image::open(dir.path().join(first_png(&stepped)))
            .unwrap()
            .to_rgb8(),
    );
    assert_ne!(
        a.as_raw(),
        b.as_raw(),
        "--steps 300 rendered the reset state"
    );
    for (flag, extra) in [
        ("--video", &["--video"][..]),
        ("--fps", &["--fps", "10"][..]),
    ] {
        let out = render(extra, "refused");
        assert_eq!(out.status.code(), Some(2), "{flag}: {}", text(&out.stderr));
        assert!(text(&out.stderr).contains(flag), "{}", text(&out.stderr));
    }
}

#[test]
fn augment_into_a_folder_in_use_prints_the_lock_hint() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    // A live run on another host (its heartbeat is fresh).
    std::fs::write(
        out.join(".lock"),
        format!(
            "{{\"pid\": {}, \"host\": \"elsewhere\"}}\n",
            std::process::id()
        ),
    )
    .unwrap();
    let episode =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/demos/click_mouse/episode_000000");
    let out = run(
        &[
            "augment",
            episode.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--replays",
            "1",
            "--max-frames",
            "2",
            "--size",
            "32",
            "--quality",
            "fast",
        ],
        dir.path(),
    );
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("in use by process"), "{stderr}");
    assert!(
        stderr.contains("hint: another run is writing this folder"),
        "{stderr}"
    );
}

#[test]
fn doctor_fails_without_ffmpeg() {
    let dir = tempfile::tempdir().unwrap();
    // A PATH with no ffmpeg on it.
    let empty = dir.path().join("bin");
    std::fs::create_dir_all(&empty).unwrap();
    let out = common::dexjoco()
        .arg("doctor")
        .env("PATH", &empty)
        .env_remove("DEXJOCO_FFMPEG")
        .env_remove("IMAGEIO_FFMPEG_EXE")
        .env_remove("VIRTUAL_ENV")
        .current_dir(dir.path())
        .output()
        .expect("binary runs");
    let stdout = text(&out.stdout);
    assert!(stdout.contains("[MISSING] no ffmpeg"), "{stdout}");
    // Both ways to get one: the system's package, or the wheel's extra.
    assert!(
        stdout.contains("apt install ffmpeg")
            && stdout.contains("pip install 'dexjoco-data[ffmpeg]'"),
        "{stdout}"
    );
    assert_eq!(out.status.code(), Some(1), "{stdout}");
}

#[test]
fn a_failing_command_prints_each_cause_once() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("runs.json");
    std::fs::write(&file, "x\n").unwrap();
    let out = run(
        &["stats", "--language-eval", file.to_str().unwrap()],
        dir.path(),
    );
    let stderr = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("Caused by:"), "{stderr}");
    assert_eq!(
        stderr.matches("expected value at line 1 column 1").count(),
        1,
        "{stderr}"
    );
}
