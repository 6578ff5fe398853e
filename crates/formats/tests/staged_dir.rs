//! Folders written whole: a staging folder beside the output, renamed into place under
//! the output's lock; what a killed run leaves (its staging folder, a replacement cut
//! between its two renames) is cleaned up by the next run.

use dexjoco_formats::fs::{StagedDir, aside_path, is_within, output_lock_name, overlaps, resolve};
use dexjoco_formats::{DirLock, FormatError};

#[test]
fn a_staged_folder_replaces_the_old_one_whole_and_leaves_nothing_beside() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ds");
    fs_err::create_dir_all(&out).unwrap();
    fs_err::write(out.join("stale.txt"), "from an earlier run").unwrap();
    let staged = StagedDir::begin(&out).unwrap();
    assert!(staged.path().starts_with(tmp.path()));
    assert!(tmp.path().join(output_lock_name(&out)).is_file(), "locked");
    fs_err::write(staged.path().join("new.txt"), "x").unwrap();
    // Nothing at `out` changes before the commit.
    assert!(out.join("stale.txt").is_file());
    staged.commit().unwrap();
    let names: Vec<_> = fs_err::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, ["new.txt"]);
    let beside: Vec<_> = fs_err::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(beside, ["ds"], "no staging, aside or lock file left");
}

#[test]
fn a_second_writer_of_the_same_folder_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ds");
    let first = StagedDir::begin(&out).unwrap();
    match StagedDir::begin(&out) {
        Err(FormatError::Locked { pid, .. }) => assert_eq!(pid, std::process::id()),
        other => panic!("expected Locked, got {other:?}"),
    }
    // Another folder beside it is another lock.
    let other = StagedDir::begin(&tmp.path().join("other")).unwrap();
    drop((first, other));
    // Dropped uncommitted: the staging folders are gone, nothing was written.
    assert_eq!(fs_err::read_dir(tmp.path()).unwrap().count(), 0);
}

#[test]
fn leftovers_of_a_killed_run_are_cleaned_and_a_cut_replacement_is_undone() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("ds");
    // A killed run's staging folder (its pid is gone: the lock is free).
    let leaked = tmp.path().join(".ds.partial-4000000");
    fs_err::create_dir_all(leaked.join("data")).unwrap();
    // Killed between the two renames: the old dataset aside, `out` missing.
    let aside = aside_path(&out);
    assert_eq!(aside, tmp.path().join(".ds.old"));
    fs_err::create_dir_all(&aside).unwrap();
    fs_err::write(aside.join("old.txt"), "the previous dataset").unwrap();
    // Someone else's folder of a similar name is not touched.
    fs_err::create_dir_all(tmp.path().join(".ds.partial-notes")).unwrap();

    let staged = StagedDir::begin(&out).unwrap();
    assert!(
        !leaked.exists(),
        "the killed run's staging folder is removed"
    );
    assert!(!aside.exists());
    assert_eq!(
        fs_err::read_to_string(out.join("old.txt")).unwrap(),
        "the previous dataset",
        "the previous copy is put back"
    );
    assert!(tmp.path().join(".ds.partial-notes").exists());
    drop(staged);

    // Killed after the second rename, before removing the old copy: the old one goes.
    fs_err::create_dir_all(&aside).unwrap();
    drop(StagedDir::begin(&out).unwrap());
    assert!(!aside.exists());
    assert!(out.join("old.txt").is_file());
}

#[test]
fn paths_are_compared_resolved() {
    let tmp = tempfile::tempdir().unwrap();
    let w = tmp.path().join("w");
    fs_err::create_dir_all(w.join("ingest")).unwrap();
    std::os::unix::fs::symlink(&w, tmp.path().join("link")).unwrap();
    assert!(overlaps(&w, &w.join("ingest")));
    assert!(overlaps(&tmp.path().join("link/ingest/../ingest"), &w));
    assert!(is_within(&tmp.path().join("link/ingest/new/deeper"), &w));
    assert!(!overlaps(&w.join("ingest"), &w.join("convert")));
    assert_eq!(resolve(&tmp.path().join("link/x/..")), resolve(&w));
    // A target that names no folder (`..`, `.`) is resolved before staging beside it.
    let staged = StagedDir::begin(&w.join("ingest/..")).unwrap();
    assert_eq!(staged.target(), resolve(&w));
    assert!(staged.path().starts_with(resolve(tmp.path())));
    drop(staged);
    // A lock of another name in the folder does not block a staged folder.
    let _lock = DirLock::acquire(&w).unwrap();
    drop(StagedDir::begin(&w.join("convert")).unwrap());
}
