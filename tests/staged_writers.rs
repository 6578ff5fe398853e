//! Every command that writes stages and renames, and replaces an earlier run's output only
//! with `--overwrite`: `scripted` (a smaller rerun leaves no stale episode), `render`,
//! `cameras`; `export` goes on past a bad episode, names it and the MCAP inputs it leaves
//! out, and exits 3.

use std::path::Path;
use std::process::{Command, Output};

mod common;

fn cli() -> Command {
    let mut c = common::dexjoco();
    c.current_dir(dexjoco_testkit::workspace_root())
        .env("DEXJOCO_LOG", "warn");
    c
}

fn run(c: &mut Command) -> (Option<i32>, String) {
    let out: Output = c.output().expect("the binary runs");
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The entries of `dir`, sorted (hidden ones too: no staging may be left).
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs_err::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// A rerun without `--overwrite` is refused with exit 1, naming `existing`, and
/// changes nothing.
fn refused(c: &mut Command, existing: &Path, dir: &Path) {
    let before = dexjoco_testkit::file_tree(dir);
    let listed = names(dir);
    let (code, stderr) = run(c);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "'{}' already exists: pass --overwrite to replace it",
            existing.display()
        )),
        "{stderr}"
    );
    assert_eq!(dexjoco_testkit::file_tree(dir), before);
    assert_eq!(names(dir), listed);
}

#[test]
fn scripted_replaces_its_task_folder_whole_and_only_with_overwrite() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("scripted");
    let scripted = |episodes: &str, extra: &[&str]| {
        let mut c = cli();
        c.args([
            "-q",
            "scripted",
            "--task",
            "click_mouse",
            "--episodes",
            episodes,
        ])
        .arg("--out")
        .arg(&out)
        .args(extra);
        c
    };
    let (code, stderr) = run(&mut scripted("2", &[]));
    assert_eq!(code, Some(0), "{stderr}");
    let task_dir = out.join("click_mouse");
    assert_eq!(names(&task_dir), ["episode_000000", "episode_000001"]);
    assert_eq!(names(&out), ["click_mouse"]);

    refused(&mut scripted("1", &[]), &task_dir, &out);

    // A smaller rerun with --overwrite leaves no episode of the bigger one.
    let (code, stderr) = run(&mut scripted("1", &["--overwrite"]));
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(names(&task_dir), ["episode_000000"]);
    assert_eq!(names(&out), ["click_mouse"]);

    // A folder holding what scripted does not write is not replaced.
    fs_err::write(task_dir.join("notes.txt"), b"mine").unwrap();
    let (code, stderr) = run(&mut scripted("1", &["--overwrite"]));
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("holds 'notes.txt'"), "{stderr}");
    assert!(task_dir.join("notes.txt").exists());
}

#[test]
fn render_and_cameras_replace_files_only_with_overwrite() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("render");
    let render = |extra: &[&str]| {
        let mut c = cli();
        c.args(["-q", "render", "--size", "32", "--quality", "fast", "--out"])
            .arg(&out)
            .args(extra);
        c
    };
    let (code, stderr) = run(&mut render(&[]));
    assert_eq!(code, Some(0), "{stderr}");
    let written = names(&out);
    assert!(
        written.contains(&"tabletop_front.png".to_owned()),
        "{written:?}"
    );
    refused(&mut render(&[]), &out.join("tabletop_front.png"), &out);
    let (code, stderr) = run(&mut render(&["--overwrite"]));
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(names(&out), written);

    let pools = tmp.path().join("pools");
    let pool = pools.join("pool.json");
    let cameras = |extra: &[&str]| {
        let mut c = cli();
        c.args(["-q", "cameras", "--task", "click_mouse", "--count", "2"])
            .args(["--candidates", "4", "--out"])
            .arg(&pool)
            .args(extra);
        c
    };
    let (code, stderr) = run(&mut cameras(&[]));
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(names(&pools), ["pool.json"]);
    refused(&mut cameras(&["--preview"]), &pool, &pools);
    let (code, stderr) = run(&mut cameras(&["--overwrite", "--preview"]));
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(names(&pools), ["pool.json", "pool_preview.png"]);
}

#[test]
fn export_goes_on_past_a_bad_episode_and_names_it_and_the_mcap_inputs() {
    let tmp = tempfile::tempdir().unwrap();
    let input = common::convert_input(tmp.path());
    let good = input.join("click_mouse/episode_000000");
    let bad = input.join("click_mouse/episode_000001");
    // An MCAP log among the inputs: one export of the good episode.
    let first = tmp.path().join("first");
    let (code, stderr) = run(cli()
        .args(["-q", "export", "--to", "mcap"])
        .arg(&good)
        .arg("--out")
        .arg(&first));
    assert_eq!(code, Some(0), "{stderr}");
    let log = input.join("log.mcap");
    fs_err::copy(first.join("click_mouse_episode_000000.mcap"), &log).unwrap();
    // The second episode loses its actions.
    fs_err::remove_dir_all(bad.join("replay.zarr/data/action")).unwrap();

    let out = tmp.path().join("out");
    let mut export = cli();
    export
        .args(["-q", "export", "--to", "mcap"])
        .arg(&input)
        .arg("--out")
        .arg(&out);
    let (code, stderr) = run(&mut export);
    assert_eq!(code, Some(3), "{stderr}");
    assert_eq!(names(&out), ["click_mouse_episode_000000.mcap"]);
    assert!(
        stderr.contains(&format!("SKIPPED: {}: ", bad.display())),
        "{stderr}"
    );
    assert!(
        stderr.contains(&format!("SKIPPED: {}: an MCAP log already", log.display())),
        "{stderr}"
    );
}
