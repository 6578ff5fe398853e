//! `augment` validates before it spends: an unknown `--camera`, an EGL device the machine
//! does not list, a `DEXJOCO_EGL_DEVICE` that is not an index and a renderer that does not
//! open all fail at once, before the physics pass and before anything is written; a
//! finalize with nothing left to render starts no worker process (nor needs a renderer).

use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

mod common;

const EPISODE: &str = "datasets/demos/click_mouse/episode_000000";

/// `augment` of one sample episode, one replay, small and short (12 frames: the task is
/// not done yet, so `--keep-failed` keeps the replay), into `out`, with `extra` arguments.
fn augment(out: &Path, extra: &[&str]) -> Command {
    let mut c = common::dexjoco();
    c.current_dir(dexjoco_testkit::workspace_root())
        .args(["-j", "1", "augment", EPISODE, "--replays", "1"])
        .args(["--size", "32", "--quality", "fast", "--max-frames", "12"])
        .args(["--keep-failed", "--out"])
        .arg(out)
        .args(extra);
    c
}

/// Runs `c`, checks its exit code and that it ended within `limit`; returns its stderr.
fn fails_with(mut c: Command, code: i32, limit: Duration) -> String {
    let started = Instant::now();
    let out: Output = c.output().expect("the binary runs");
    let seconds = started.elapsed();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(code), "stderr: {stderr}");
    assert!(seconds < limit, "took {seconds:?}; stderr: {stderr}");
    stderr
}

#[test]
fn an_unknown_camera_is_a_usage_error_before_any_work() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("aug");
    let stderr = fails_with(
        augment(&out, &["--camera", "front", "--camera", "nope"]),
        2,
        Duration::from_secs(30),
    );
    assert!(
        stderr.contains("--camera 'nope'") && stderr.contains("click_mouse"),
        "{stderr}"
    );
    // The cameras the scene has are named.
    assert!(
        stderr.contains("front") && stderr.contains("handcam_rgb"),
        "{stderr}"
    );
    // Found before the output was touched: no folder, no settings, no staging.
    assert!(!out.exists(), "{stderr}");
}

#[test]
fn an_egl_device_the_machine_lacks_is_a_usage_error() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("aug");
    let stderr = fails_with(
        augment(&out, &["--egl-devices", "99"]),
        2,
        Duration::from_secs(30),
    );
    assert!(
        stderr.contains("--egl-devices 99") && stderr.contains("no EGL device 99"),
        "{stderr}"
    );
    assert!(stderr.contains("doctor"), "{stderr}");
    assert!(!out.exists(), "{stderr}");

    let mut c = augment(&out, &[]);
    c.env(dexjoco_render::EGL_DEVICE_ENV, "99");
    let stderr = fails_with(c, 2, Duration::from_secs(30));
    assert!(stderr.contains("DEXJOCO_EGL_DEVICE=99"), "{stderr}");
}

#[test]
fn a_egl_device_variable_that_is_not_an_index_is_an_error() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("aug");
    let mut c = augment(&out, &[]);
    c.env(dexjoco_render::EGL_DEVICE_ENV, "abc");
    let stderr = fails_with(c, 2, Duration::from_secs(30));
    assert!(stderr.contains("DEXJOCO_EGL_DEVICE='abc'"), "{stderr}");
    assert!(!out.exists(), "{stderr}");
}

#[test]
fn every_rendering_command_refuses_a_egl_device_variable_that_is_not_an_index() {
    let tmp = tempfile::tempdir().unwrap();
    for args in [
        &["render", "--steps", "1"][..],
        &["cameras", "--task", "click_mouse", "--count", "2"],
        &["bench", "render", "--frames", "1"],
    ] {
        let mut c = common::dexjoco();
        c.current_dir(tmp.path())
            .args(args)
            .env(dexjoco_render::EGL_DEVICE_ENV, "abc");
        let stderr = fails_with(c, 2, Duration::from_secs(30));
        assert!(
            stderr.contains("DEXJOCO_EGL_DEVICE='abc'"),
            "{args:?}: {stderr}"
        );
    }
}

/// Mesa's EGL only, with its drivers out of reach: EGL lists Mesa's devices, and no
/// context opens on any of them (as on a machine with a broken driver install).
fn broken_renderer(c: &mut Command) {
    c.env(
        "__EGL_VENDOR_LIBRARY_FILENAMES",
        "/usr/share/glvnd/egl_vendor.d/50_mesa.json",
    )
    .env("LIBGL_DRIVERS_PATH", "/nonexistent");
}

#[test]
fn a_renderer_that_does_not_open_fails_in_seconds_naming_the_device() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("aug");
    let mut c = augment(&out, &[]);
    broken_renderer(&mut c);
    let stderr = fails_with(c, 1, Duration::from_secs(30));
    assert!(
        stderr.contains("offscreen rendering is unavailable on the default EGL device"),
        "{stderr}"
    );
    // The device that failed, and where to look.
    assert!(stderr.contains("device 0 ("), "{stderr}");
    assert!(stderr.contains("dexjoco-data doctor"), "{stderr}");
    // Before the physics pass and the output's settings: the folder made for the run is
    // gone again.
    assert!(!out.exists(), "{stderr}");
}

#[test]
fn a_finalize_with_nothing_left_starts_no_worker_and_needs_no_renderer() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("aug");
    let first = augment(&out, &["-v"]).output().unwrap();
    let first_err = String::from_utf8_lossy(&first.stderr);
    assert_eq!(first.status.code(), Some(3), "{first_err}");
    assert!(
        first_err.contains("started worker process 0"),
        "{first_err}"
    );
    let before = dexjoco_testkit::file_tree(&out.join("click_mouse"));

    // Everything is on disk: the rerun writes the same report and starts no worker, and
    // a machine that cannot render can finalize.
    let mut c = augment(&out, &["-v"]);
    broken_renderer(&mut c);
    let again = c.output().unwrap();
    let again_err = String::from_utf8_lossy(&again.stderr);
    assert_eq!(again.status.code(), Some(3), "{again_err}");
    assert!(!again_err.contains("started worker process"), "{again_err}");
    assert!(
        again_err.contains("nothing to do: no worker process started"),
        "{again_err}"
    );
    assert_eq!(dexjoco_testkit::file_tree(&out.join("click_mouse")), before);
}
