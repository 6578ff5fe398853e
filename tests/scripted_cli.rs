//! The `scripted` command end to end: demonstrations planned from random resets are
//! written in the raw layout, read back as episodes of the task that start from their
//! reset, byte-identical for the same seed; an unknown task is refused.

use std::path::Path;
use std::process::Command;

mod common;

fn cli() -> Command {
    let mut c = common::dexjoco();
    c.env("DEXJOCO_LOG", "warn");
    c
}

fn scripted(out: &Path, seed: &str) -> std::process::Output {
    cli()
        .args(["-q", "--seed", seed, "scripted", "--task", "pinch_tongs"])
        .args(["--episodes", "2", "--out"])
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn scripted_writes_successful_demonstrations_deterministically() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b, c) = (
        tmp.path().join("a"),
        tmp.path().join("b"),
        tmp.path().join("c"),
    );
    let first = scripted(&a, "5");
    assert!(
        first.status.success(),
        "{}",
        String::from_utf8_lossy(&first.stderr)
    );
    let summary = String::from_utf8_lossy(&first.stderr);
    assert!(
        summary.contains("pinch_tongs: 2/2 plans succeeded"),
        "{summary}"
    );
    for k in 0..2 {
        let dir = a.join(format!("pinch_tongs/episode_{k:06}"));
        let ep = dexjoco_formats::read_episode(&dir, dexjoco_core::TaskSet::builtin()).unwrap();
        assert_eq!(ep.task, "pinch_tongs");
        assert!(ep.len() > 100 && ep.len() <= 1000, "{} steps", ep.len());
    }
    // Same seed: the same bytes; another seed: other resets.
    assert!(scripted(&b, "5").status.success());
    assert_eq!(
        dexjoco_testkit::file_tree(&a),
        dexjoco_testkit::file_tree(&b)
    );
    assert!(scripted(&c, "6").status.success());
    assert_ne!(
        dexjoco_testkit::file_tree(&a),
        dexjoco_testkit::file_tree(&c)
    );
}

#[test]
fn scripted_refuses_an_unknown_task_as_a_usage_error() {
    let tmp = tempfile::tempdir().unwrap();
    let out = cli()
        .args(["scripted", "--task", "no_such_task", "--out"])
        .arg(tmp.path())
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(2),
        "unknown task: exit 2 in every command"
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("unknown task 'no_such_task'"), "{err}");
    assert!(
        err.contains("bimanual_hanoi"),
        "the hint lists the tasks: {err}"
    );
    assert!(std::fs::read_dir(tmp.path()).unwrap().next().is_none());
}
