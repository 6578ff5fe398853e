//! A corpus of broken inputs next to good ones in one run: each broken input gets its
//! named problem and is quarantined, the good ones land, and re-runs are idempotent.

use std::path::{Path, PathBuf};

use dexjoco_core::{Episode, TaskSet, TaskSpec, synth};
use dexjoco_formats::{Status, discover, raw};

fn task_info(id: &str) -> Option<&'static TaskSpec> {
    TaskSpec::builtin(id)
}

fn read_stored_episode(dir: &Path) -> dexjoco_formats::Result<Episode> {
    dexjoco_formats::read_episode(dir, TaskSet::builtin())
}
use dexjoco_formats::EpisodeMeta;
use dexjoco_formats::ProblemCode;
use dexjoco_formats::mcap::write_episode_mcap;
use dexjoco_ingest::{IngestOptions, Outcome, QUARANTINE, REASON_FILE, Store};

fn write_raw(dir: &Path, ep: &Episode) {
    raw::write_replay_zarr(dir, ep).unwrap();
}

fn good(task: &str, frames: usize, seed: u64) -> Episode {
    synth::episode(task_info(task).unwrap(), frames, seed)
}

/// Builds the corpus; returns (input root, expected (file name, code) of the bad ones,
/// names of the good ones).
fn corpus(root: &Path) -> (Vec<(PathBuf, ProblemCode)>, Vec<PathBuf>) {
    let ok = good_inputs(root);
    let mut bad = vec![truncated_mcap(root, &ok[2])];
    bad.extend(broken_raw_folders(root));
    bad.extend(broken_files(root));
    bad.extend(out_of_range_values(root));
    (bad, ok)
}

/// Good: two raw folders and one MCAP file (last).
fn good_inputs(root: &Path) -> Vec<PathBuf> {
    let mut ok = Vec::new();
    let p = root.join("click_mouse/episode_000000");
    write_raw(&p, &good("click_mouse", 40, 1));
    fs_err::create_dir_all(p.join("videos")).unwrap();
    fs_err::write(p.join("videos/front.mp4"), b"not really h264").unwrap();
    fs_err::write(p.join("videos/front_depth.npz"), b"not really npz").unwrap();
    ok.push(p);
    let p = root.join("bimanual_hanoi/episode_000000");
    write_raw(&p, &good("bimanual_hanoi", 40, 2));
    ok.push(p);
    let p = root.join("good.mcap");
    let ep = good("pinch_tongs", 40, 3);
    write_episode_mcap(
        &p,
        &ep,
        task_info("pinch_tongs").unwrap(),
        &EpisodeMeta::default(),
    )
    .unwrap();
    ok.push(p);
    ok
}

/// Truncated MCAP: a good file cut in half.
fn truncated_mcap(root: &Path, good_mcap: &Path) -> (PathBuf, ProblemCode) {
    let bytes = fs_err::read(good_mcap).unwrap();
    let t = root.join("truncated.mcap");
    let ep = good("water_plant", 40, 4);
    write_episode_mcap(
        &t,
        &ep,
        task_info("water_plant").unwrap(),
        &EpisodeMeta::default(),
    )
    .unwrap();
    let full = fs_err::read(&t).unwrap();
    fs_err::write(&t, &full[..full.len() / 2]).unwrap();
    assert_ne!(bytes.len(), 0);
    (t, ProblemCode::Truncated)
}

/// Raw folders with a damaged array, or of an unknown task.
fn broken_raw_folders(root: &Path) -> Vec<(PathBuf, ProblemCode)> {
    let mut bad = Vec::new();
    // Wrong dimensions: click_mouse state with 37 columns instead of 31.
    let mut ep = good("click_mouse", 40, 5);
    let wide = dexjoco_core::FrameArray::zeros(40, 37);
    ep.arrays.insert(Episode::STATE.into(), wide);
    let p = root.join("click_mouse/episode_000001");
    write_raw(&p, &ep);
    bad.push((p, ProblemCode::WrongDimensions));

    // NaN in the state.
    let mut ep = good("hammer_nail", 40, 6);
    ep.arrays.get_mut(Episode::STATE).unwrap().row_mut(17)[4] = f64::NAN;
    let p = root.join("hammer_nail/episode_000000");
    write_raw(&p, &ep);
    bad.push((p, ProblemCode::NotFinite));

    // Missing array: no data/state.
    let p = root.join("hammer_nail/episode_000001");
    write_raw(&p, &good("hammer_nail", 40, 7));
    fs_err::remove_dir_all(p.join("replay.zarr/data/state")).unwrap();
    bad.push((p, ProblemCode::MissingArray));

    // Wrong dtype: action declared int32.
    let p = root.join("hammer_nail/episode_000002");
    write_raw(&p, &good("hammer_nail", 40, 8));
    let zarray = p.join("replay.zarr/data/action/.zarray");
    let text = fs_err::read_to_string(&zarray)
        .unwrap()
        .replace("<f8", "<i4");
    fs_err::write(&zarray, text).unwrap();
    bad.push((p, ProblemCode::WrongDtype));

    // episode_ends says 39 frames where the arrays hold 40.
    let p = root.join("fold_glasses/episode_000000");
    write_raw(&p, &good("fold_glasses", 40, 9));
    let chunk = p.join("replay.zarr/meta/episode_ends/0");
    let mut b = fs_err::read(&chunk).unwrap();
    b[..8].copy_from_slice(&39i64.to_le_bytes());
    fs_err::write(&chunk, b).unwrap();
    bad.push((p, ProblemCode::EpisodeEndsMismatch));

    // Unknown task.
    let p = root.join("juggle_knives/episode_000000");
    write_raw(&p, &good("click_mouse", 40, 10));
    bad.push((p, ProblemCode::UnknownTask));
    bad
}

/// Files that are empty, unreadable, or not MCAP at all.
fn broken_files(root: &Path) -> Vec<(PathBuf, ProblemCode)> {
    let mut bad = Vec::new();
    // Empty file.
    let p = root.join("empty.mcap");
    fs_err::write(&p, b"").unwrap();
    bad.push((p, ProblemCode::EmptyFile));

    // Unreadable file: a link to nothing (permissions do not stop root).
    let p = root.join("unreadable.mcap");
    std::os::unix::fs::symlink(root.join("does-not-exist"), &p).unwrap();
    bad.push((p, ProblemCode::Unreadable));

    // Not an MCAP at all.
    let p = root.join("garbage.mcap");
    fs_err::write(&p, b"this is not an mcap file").unwrap();
    bad.push((p, ProblemCode::Corrupt));
    bad
}

/// Out of range values: dh above 0.05, a hand target beyond its range, a quaternion
/// that is not unit, timestamps that go backwards, more frames than the cap.
fn out_of_range_values(root: &Path) -> Vec<(PathBuf, ProblemCode)> {
    let mut bad = Vec::new();
    let mut ep = good("pinch_tongs", 40, 11);
    ep.arrays.get_mut(Episode::STATE).unwrap().row_mut(3)[30] = 0.2;
    let p = root.join("pinch_tongs/episode_000000");
    write_raw(&p, &ep);
    bad.push((p, ProblemCode::TableOffsetOutOfRange));
    let mut ep = good("pinch_tongs", 40, 12);
    ep.arrays.get_mut(Episode::ACTION).unwrap().row_mut(9)[7 + 12] = 0.0 - 1.0;
    let p = root.join("pinch_tongs/episode_000001");
    write_raw(&p, &ep);
    bad.push((p, ProblemCode::HandOutOfRange));
    let mut ep = good("pinch_tongs", 40, 13);
    ep.arrays.get_mut(Episode::ACTION).unwrap().row_mut(2)[3] = 3.0;
    let p = root.join("pinch_tongs/episode_000002");
    write_raw(&p, &ep);
    bad.push((p, ProblemCode::NotUnitQuaternion));
    let mut ep = good("pinch_tongs", 40, 14);
    ep.arrays.get_mut(Episode::TIMESTAMP).unwrap().row_mut(20)[0] = 0.1;
    let p = root.join("pinch_tongs/episode_000003");
    write_raw(&p, &ep);
    bad.push((p, ProblemCode::Timestamps));
    let p = root.join("pinch_tongs/episode_000004");
    write_raw(&p, &good("pinch_tongs", 1001, 15));
    bad.push((p, ProblemCode::TooLong));
    bad
}

fn run(input: &Path, store: &Path, force: bool) -> dexjoco_ingest::IngestSummary {
    let mut s = Store::open(store).unwrap();
    let sources = discover(&[input.to_path_buf()], Some(store)).unwrap();
    s.ingest(
        &sources,
        &IngestOptions {
            force,
            ..IngestOptions::default()
        },
        &dexjoco_core::NoProgress,
    )
    .unwrap()
}

#[test]
fn broken_inputs_are_quarantined_with_named_problems_and_good_ones_land() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    let (bad, ok) = corpus(&input);
    let store = tmp.path().join("store");
    let summary = run(&input, &store, false);
    assert_eq!(summary.sources.len(), bad.len() + ok.len());

    assert_quarantined_with_named_problems(&summary, &bad, &store);
    assert_fields_and_frames_named(&summary);
    assert_good_ones_landed(&summary, &ok, &store);
    assert_eq!(summary.rejected(), bad.len());
    assert_manifest_lists_all(&store, bad.len(), ok.len());
    assert!(!store.join(".staging").exists());
}

/// The report of the source at `path`.
fn report<'a>(
    summary: &'a dexjoco_ingest::IngestSummary,
    path: &Path,
) -> &'a dexjoco_ingest::SourceReport {
    summary
        .sources
        .iter()
        .find(|s| s.source == path)
        .unwrap_or_else(|| panic!("{} not reported", path.display()))
}

/// Each broken input is quarantined with its code, its problems name the file and the
/// episode, and its reason and copy are kept.
fn assert_quarantined_with_named_problems(
    summary: &dexjoco_ingest::IngestSummary,
    bad: &[(PathBuf, ProblemCode)],
    store: &Path,
) {
    for (path, code) in bad {
        let r = report(summary, path);
        assert_eq!(r.outcome, Outcome::Quarantined, "{}: {r:?}", path.display());
        assert!(
            r.problems.iter().any(|p| p.code == *code),
            "{}: expected {code}, got {:?}",
            path.display(),
            r.problems
        );
        // Every problem names the file and the episode.
        for p in &r.problems {
            assert_eq!(p.file.as_deref(), Some(path.as_path()), "{p:?}");
            assert_eq!(p.episode.as_deref(), Some(r.id.as_str()), "{p:?}");
        }
        let q = store.join(QUARANTINE).join(&r.id);
        assert!(q.join(REASON_FILE).is_file(), "{}", q.display());
        if *code != ProblemCode::Unreadable {
            let copy = q.join("source").join(path.file_name().unwrap());
            assert!(copy.exists(), "quarantined copy {}", copy.display());
        }
    }
}

/// Field and frame where the problem has them.
fn assert_fields_and_frames_named(summary: &dexjoco_ingest::IngestSummary) {
    let ending = |tail: &str| {
        summary
            .sources
            .iter()
            .find(|s| s.source.ends_with(tail))
            .unwrap()
    };
    let nan = ending("hammer_nail/episode_000000");
    let p = &nan.problems[0];
    assert_eq!(
        (p.field.as_deref(), p.frame),
        (Some("state[4]"), Some(17)),
        "{p:?}"
    );
    assert!(
        p.message.contains("frame 17") && p.message.contains("state[4]"),
        "{}",
        p.message
    );
    let dims = ending("click_mouse/episode_000001");
    assert_eq!(dims.problems[0].field.as_deref(), Some("state"));
    let hand = ending("pinch_tongs/episode_000001");
    assert_eq!(
        (hand.problems[0].field.as_deref(), hand.problems[0].frame),
        (Some("action[19]"), Some(9))
    );
}

/// The good inputs land whole, videos with their episode byte for byte.
fn assert_good_ones_landed(summary: &dexjoco_ingest::IngestSummary, ok: &[PathBuf], store: &Path) {
    for path in ok {
        let r = summary.sources.iter().find(|s| &s.source == path).unwrap();
        assert_eq!(r.outcome, Outcome::Landed, "{r:?}");
        let ep = read_stored_episode(&store.join(&r.path)).unwrap();
        assert_eq!(ep.len(), 40);
    }
    // Videos travel with their episode, byte for byte.
    let r = summary.sources.iter().find(|s| s.source == ok[0]).unwrap();
    let landed = store.join(&r.path);
    assert_eq!(
        fs_err::read(landed.join("videos/front.mp4")).unwrap(),
        b"not really h264"
    );
    let ep = read_stored_episode(&landed).unwrap();
    assert_eq!(ep.cameras.len(), 1);
    assert_eq!(ep.cameras[0].name, "front");
    assert!(ep.cameras[0].depth.is_some());
}

/// The reopened store's manifest lists every input and names every problem code.
fn assert_manifest_lists_all(store: &Path, bad: usize, ok: usize) {
    let opened = Store::open(store).unwrap();
    let m = opened.manifest();
    assert_eq!(m.episodes.len(), bad + ok);
    assert_eq!(
        m.episodes.iter().filter(|e| e.status == Status::Ok).count(),
        ok
    );
    let json = fs_err::read_to_string(store.join("manifest.json")).unwrap();
    for code in [
        "truncated",
        "wrong_dimensions",
        "not_finite",
        "missing_array",
        "wrong_dtype",
        "episode_ends_mismatch",
        "unknown_task",
        "empty_file",
        "unreadable",
    ] {
        assert!(
            json.contains(&format!("\"code\": \"{code}\"")),
            "manifest names {code}"
        );
    }
}

#[test]
fn reruns_are_idempotent_and_force_redoes_in_place() {
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    let (bad, ok) = corpus(&input);
    let store = tmp.path().join("store");
    let first = run(&input, &store, false);
    let manifest1 = fs_err::read_to_string(store.join("manifest.json")).unwrap();

    let second = run(&input, &store, false);
    assert_eq!(second.count(Outcome::AlreadyPresent), ok.len());
    assert_eq!(second.count(Outcome::Quarantined), bad.len());
    assert_eq!(second.count(Outcome::Landed), 0);
    let manifest2 = fs_err::read_to_string(store.join("manifest.json")).unwrap();
    assert_eq!(manifest1, manifest2, "a re-run changes nothing");
    for (a, b) in first.sources.iter().zip(&second.sources) {
        assert_eq!((&a.id, &a.path), (&b.id, &b.path));
    }

    let third = run(&input, &store, true);
    assert_eq!(third.count(Outcome::Replaced), ok.len());
    for (a, b) in first.sources.iter().zip(&third.sources) {
        assert_eq!(
            (&a.id, &a.path),
            (&b.id, &b.path),
            "force keeps ids and folders"
        );
    }
    // One folder per good episode, nothing else.
    let mut dirs = 0;
    for task in ["click_mouse", "bimanual_hanoi", "pinch_tongs"] {
        dirs += fs_err::read_dir(store.join(task)).unwrap().count();
    }
    assert_eq!(dirs, ok.len());

    // The same content under another name is ingested once.
    let copy = input.join("copy_of_good.mcap");
    fs_err::copy(input.join("good.mcap"), &copy).unwrap();
    let fourth = run(&input, &store, false);
    let r = fourth.sources.iter().find(|s| s.source == copy).unwrap();
    assert_eq!(r.outcome, Outcome::AlreadyPresent);

    // Within one run: a second copy of a good input is a duplicate; a second empty file
    // is rejected like the first.
    let fresh = tmp.path().join("store-fresh");
    fs_err::write(input.join("zz_empty_again.mcap"), b"").unwrap();
    let fifth = run(&input, &fresh, false);
    // Inputs are taken in path order: copy_of_good.mcap comes first.
    let r = fifth.sources.iter().find(|s| s.source == copy).unwrap();
    assert_eq!(r.outcome, Outcome::Landed);
    let r = fifth
        .sources
        .iter()
        .find(|s| s.source == input.join("good.mcap"))
        .unwrap();
    assert_eq!(r.outcome, Outcome::Duplicate);
    assert_eq!(r.problems[0].code, ProblemCode::Duplicate);
    let r = fifth
        .sources
        .iter()
        .find(|s| s.source.ends_with("zz_empty_again.mcap"))
        .unwrap();
    assert_eq!(r.outcome, Outcome::Quarantined);
    assert_eq!(r.problems[0].code, ProblemCode::EmptyFile);
    assert_eq!(fifth.rejected(), bad.len() + 1);
}

#[test]
fn a_store_is_used_by_one_process_at_a_time_and_stale_locks_are_taken_over() {
    let tmp = tempfile::tempdir().unwrap();
    let store = tmp.path().join("store");
    let first = Store::open(&store).unwrap();
    match Store::open(&store) {
        Err(dexjoco_ingest::IngestError::Format(dexjoco_formats::FormatError::Locked {
            pid,
            ..
        })) => assert_eq!(pid, std::process::id()),
        other => panic!("expected Locked, got {other:?}"),
    }
    drop(first);
    assert!(!store.join(dexjoco_formats::LOCK_FILE).exists());
    // A lock left by a process that has ended (a killed run) does not block.
    fs_err::write(store.join(dexjoco_formats::LOCK_FILE), u32::MAX.to_string()).unwrap();
    Store::open(&store).unwrap();
}

#[test]
fn discovery_finds_raw_folders_and_mcap_files_and_survives_link_loops() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("in");
    write_raw(
        &root.join("a/click_mouse/episode_000000"),
        &good("click_mouse", 5, 1),
    );
    write_raw(
        &root.join("b/pick_bucket_demo_3_2026-01-01_00-00-00_000000"),
        &good("pick_bucket", 5, 2),
    );
    fs_err::write(root.join("b/x.MCAP"), b"").unwrap();
    fs_err::write(root.join("b/notes.txt"), b"ignored").unwrap();
    std::os::unix::fs::symlink(&root, root.join("a/loop")).unwrap();
    let store = root.join("store");
    fs_err::create_dir_all(&store).unwrap();
    fs_err::write(store.join("inside_the_store.mcap"), b"").unwrap();
    let found = discover(std::slice::from_ref(&root), Some(&store)).unwrap();
    let names: Vec<String> = found
        .iter()
        .map(|s| s.path.strip_prefix(&root).unwrap().display().to_string())
        .collect();
    assert_eq!(
        names,
        [
            "a/click_mouse/episode_000000",
            "b/pick_bucket_demo_3_2026-01-01_00-00-00_000000",
            "b/x.MCAP"
        ]
    );
    // A replay.zarr given directly means its episode folder.
    let one = discover(
        &[root.join("a/click_mouse/episode_000000/replay.zarr")],
        Some(&store),
    )
    .unwrap();
    assert_eq!(one[0].path, root.join("a/click_mouse/episode_000000"));
}

/// A folder's files and their bytes.
type FileTree = std::collections::BTreeMap<String, Vec<u8>>;

#[test]
fn inputs_of_the_same_content_land_once_the_same_way_every_time() {
    // Issue #44: same-content inputs staged in one folder raced (about 1 run in 20 failed
    // with "Directory not empty"). Six copies of a good log, three of a raw folder and
    // three of a rejected file, ingested 40 times over into fresh stores on 4 threads.
    let tmp = tempfile::tempdir().unwrap();
    let input = tmp.path().join("in");
    let ok = good_inputs(&input);
    for k in 0..5 {
        fs_err::copy(&ok[2], input.join(format!("copy_{k}.mcap"))).unwrap();
    }
    for k in 0..2 {
        dexjoco_formats::fs::copy_tree(
            &ok[0],
            &input.join(format!("copies_{k}/click_mouse/episode_000000")),
        )
        .unwrap();
    }
    for k in 0..3 {
        fs_err::write(input.join(format!("empty_{k}.mcap")), b"").unwrap();
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(4)
        .build()
        .unwrap();
    let mut first: Option<(Vec<(PathBuf, Outcome)>, FileTree)> = None;
    for n in 0..40 {
        let store = tmp.path().join(format!("store-{n}"));
        let summary = pool.install(|| run(&input, &store, false));
        let outcomes: Vec<(PathBuf, Outcome)> = summary
            .sources
            .iter()
            .map(|s| (s.source.clone(), s.outcome))
            .collect();
        assert!(!store.join(".staging").exists(), "run {n}");
        // One landed copy per content: the first in input order, the others duplicates.
        assert_eq!(summary.count(Outcome::Landed), 3, "run {n}: {outcomes:?}");
        assert_eq!(
            summary.count(Outcome::Duplicate),
            5 + 2,
            "run {n}: {outcomes:?}"
        );
        let tree = dexjoco_testkit::file_tree(&store);
        match &first {
            None => first = Some((outcomes, tree)),
            Some((o, t)) => {
                assert_eq!(&outcomes, o, "run {n}: other outcomes");
                assert!(&tree == t, "run {n}: another store");
            }
        }
    }
}
