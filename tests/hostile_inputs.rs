//! Damaged and hostile inputs through the binary (issue #54): datasets as they come from
//! anywhere (a field missing from info.json, a huge path-template width, absurd shapes,
//! episode ranges past any dataset, a video placement past its file's end, a dataset
//! whose files are all links with links planted where commands write), and records the
//! project does not control (evaluation records `convert` reads, `generate`'s resume log).
//! Each gives exit 0 where a default applies, else exit 1 or 2 naming the file and field;
//! nothing is written outside `--out`, no file outside the dataset changes, nothing
//! partial is left.

mod common;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use common::{dexjoco, said, succeeds};
use serde_json::Value;

/// A LeRobot v3.0 dataset of 4 episodes written by lerobot 0.6.1's own writer (one 32 px
/// camera), made once per test binary.
fn lerobot_written() -> &'static Path {
    static MADE: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    let (_, root) = MADE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("small");
        let made = dexjoco_testkit::run_python_json(
            "lerobot_small_dataset.py",
            &[root.to_str().unwrap(), "4"],
        );
        assert_eq!(made, 4);
        (dir, root)
    });
    root
}

/// A copy of the lerobot-written dataset at `to`, its info.json changed by `edit`.
fn copy_with(to: &Path, edit: impl FnOnce(&mut Value)) -> PathBuf {
    dexjoco_formats::fs::copy_tree(lerobot_written(), to).unwrap();
    let path = to.join("meta/info.json");
    let mut info: Value = serde_json::from_str(&fs_err::read_to_string(&path).unwrap()).unwrap();
    edit(&mut info);
    fs_err::write(&path, info.to_string()).unwrap();
    to.to_path_buf()
}

/// Runs `dataset <args...>`; asserts exit `code` and that the output names every one of
/// `words`; returns it.
fn dataset(args: &[&str], code: i32, words: &[&str]) -> String {
    let o = dexjoco().arg("dataset").args(args).output().unwrap();
    let text = said(&o);
    assert_eq!(o.status.code(), Some(code), "dataset {args:?}: {text}");
    for w in words {
        assert!(
            text.contains(w),
            "dataset {args:?} does not name {w:?}: {text}"
        );
    }
    assert!(!text.contains("panicked"), "{text}");
    text
}

/// No staging folder or half-written file left beside or inside `dir`'s parent.
fn nothing_partial(parent: &Path) {
    for e in walk(parent) {
        let name = e.file_name().unwrap().to_string_lossy().into_owned();
        assert!(!name.contains(".partial"), "left behind: {}", e.display());
    }
}

/// Every path under `dir`, links not followed.
fn walk(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in fs_err::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            if e.file_type().unwrap().is_dir() {
                stack.push(p.clone());
            }
            out.push(p);
        }
    }
    out
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn damaged_metadata_gives_a_default_or_a_named_error_never_a_crash() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    missing_fields_are_named_or_take_their_default(d);
    absurd_templates_and_shapes_are_refused(d);
    ranges_and_names_are_checked_before_use(d);
    nothing_partial(d);
}

/// A field missing from info.json: named where it is required, lerobot's default where
/// it has one.
fn missing_fields_are_named_or_take_their_default(d: &Path) {
    // codebase_version missing: named, in every command.
    let no_version = copy_with(&d.join("no_version"), |i| {
        i.as_object_mut().unwrap().remove("codebase_version");
    });
    for args in [vec!["info", s(&no_version)], vec!["stats", s(&no_version)]] {
        dataset(
            &args,
            1,
            &["no_version/meta/info.json", "codebase_version", "missing"],
        );
    }

    // chunks_size missing: lerobot's default (1000), written into the output.
    let no_chunks = copy_with(&d.join("no_chunks"), |i| {
        i.as_object_mut().unwrap().remove("chunks_size");
    });
    let out = |name: &str| d.join("out").join(name);
    let runs: Vec<(&str, Vec<String>)> = vec![
        ("filter", vec!["--episodes".into(), "0-1".into()]),
        ("split", vec!["--splits".into(), "a=0.5,b=0.5".into()]),
        ("trim", vec!["--frames".into(), "0=2..10".into()]),
        (
            "features",
            vec!["--remove".into(), "observation.state".into()],
        ),
        ("to-v21", vec![]),
    ];
    for (cmd, extra) in &runs {
        let mut args: Vec<&str> = vec![cmd, s(&no_chunks)];
        args.extend(extra.iter().map(String::as_str));
        let o = out(cmd);
        args.extend(["--out", s(&o)]);
        dataset(&args, 0, &[]);
    }
    let merged = out("merge");
    dataset(
        &[
            "merge",
            s(&no_chunks),
            s(lerobot_written()),
            "--out",
            s(&merged),
        ],
        0,
        &[],
    );
    let info: Value = serde_json::from_str(
        &fs_err::read_to_string(out("filter").join("meta/info.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(info["chunks_size"], 1000, "{info}");

    // robot_type and splits missing: `dataset info` describes it.
    let bare = copy_with(&d.join("bare"), |i| {
        let i = i.as_object_mut().unwrap();
        i.remove("robot_type");
        i.remove("splits");
    });
    dataset(&["info", s(&bare)], 0, &["4 episodes"]);
}

/// A path template of a huge width and shapes of absurd sizes: refused, named.
fn absurd_templates_and_shapes_are_refused(d: &Path) {
    let out = |name: &str| d.join("out").join(name);
    // A path template of a huge width: refused before any formatting.
    let wide = copy_with(&d.join("wide"), |i| {
        i["data_path"] = "data/chunk-{chunk_index:070000d}/file-{file_index:03d}.parquet".into();
    });
    let o = out("wide");
    dataset(
        &["filter", s(&wide), "--episodes", "0", "--out", s(&o)],
        1,
        &["wide/meta/info.json", "data_path", "at most 20 digits"],
    );
    assert!(!o.exists());

    // Absurd shapes: refused, never statistics of width 1 or a feature left out.
    for (name, shape) in [
        (
            "overflow",
            serde_json::json!([4_294_967_296u64, 4_294_967_296u64]),
        ),
        ("huge", serde_json::json!([1_000_000_000_000u64])),
    ] {
        let ds = copy_with(&d.join(name), |i| i["features"]["action"]["shape"] = shape);
        let before = fs_err::read(ds.join("meta/stats.json")).unwrap();
        dataset(
            &["stats", s(&ds)],
            1,
            &[&format!("{name}/meta/info.json"), "features.action.shape"],
        );
        assert_eq!(fs_err::read(ds.join("meta/stats.json")).unwrap(), before);
    }
    // A shape the data does not have: named, with the data file.
    let narrow = copy_with(&d.join("narrow"), |i| {
        i["features"]["action"]["shape"] = serde_json::json!([7])
    });
    dataset(
        &["stats", s(&narrow)],
        1,
        &["file-000.parquet", "\"action\"", "7 per frame"],
    );
}

/// Episode ranges past any dataset and a split name that is a path.
fn ranges_and_names_are_checked_before_use(d: &Path) {
    let out = |name: &str| d.join("out").join(name);
    // Ranges past any dataset: checked before they are expanded.
    let source = lerobot_written();
    for range in ["0-99999999999", "0-18446744073709551615"] {
        let started = std::time::Instant::now();
        dataset(
            &[
                "filter",
                s(source),
                "--episodes",
                range,
                "--out",
                s(&out("range")),
            ],
            1,
            &["out of range", "has episodes 0..3"],
        );
        assert!(
            started.elapsed().as_secs() < 20,
            "{range}: {:?}",
            started.elapsed()
        );
    }
    // A split named `..` would be written beside --out: refused, nothing written.
    let splits = d.join("splits");
    dataset(
        &[
            "split",
            s(source),
            "--splits",
            "..=0.5,b=0.5",
            "--out",
            s(&splits),
        ],
        2,
        &["split name \"..\"", "cannot be a file name"],
    );
    assert!(!splits.exists() && !d.join("b").exists());
}

/// Moves episode 1's video span of `ds` ten seconds later, past the end of its file.
fn place_past_the_end(ds: &Path) {
    let script = "import sys, pyarrow as pa, pyarrow.parquet as pq\n\
                  p = sys.argv[1] + '/meta/episodes/chunk-000/file-000.parquet'\n\
                  t = pq.read_table(p); d = t.to_pydict()\n\
                  for s in ('from', 'to'):\n    d[f'videos/observation.images.top/{s}_timestamp'][1] += 10\n\
                  pq.write_table(pa.Table.from_pydict(d, schema=t.schema), p)\n\
                  print(1)";
    let o = std::process::Command::new(dexjoco_testkit::python())
        .args(["-c", script, s(ds)])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn a_video_placement_past_its_files_end_is_named_before_any_cut() {
    let dir = tempfile::tempdir().unwrap();
    let ds = copy_with(&dir.path().join("late"), |_| {});
    place_past_the_end(&ds);
    for (cmd, extra) in [
        ("filter", ["--episodes", "1"]),
        ("trim", ["--frames", "1=2..10"]),
    ] {
        let o = dir.path().join(cmd);
        let mut args = vec![cmd, s(&ds)];
        args.extend(extra);
        args.extend(["--out", s(&o)]);
        dataset(
            &args,
            1,
            &["file-000.mp4", "episode 1", "but the file holds"],
        );
        assert!(!o.exists());
    }
    nothing_partial(dir.path());
}

/// The lerobot-written dataset as a Hugging Face cache holds it: every file a link into a
/// folder of blobs; and links planted where `dataset stats` writes, to files outside.
fn linked_copy(d: &Path) -> (PathBuf, Vec<(PathBuf, Vec<u8>)>) {
    let blobs = d.join("blobs");
    let root = d.join("snapshot");
    for (k, file) in walk(lerobot_written())
        .into_iter()
        .filter(|p| p.is_file())
        .enumerate()
    {
        let rel = file.strip_prefix(lerobot_written()).unwrap();
        let blob = blobs.join(k.to_string());
        fs_err::create_dir_all(&blobs).unwrap();
        fs_err::copy(&file, &blob).unwrap();
        let link = root.join(rel);
        fs_err::create_dir_all(link.parent().unwrap()).unwrap();
        std::os::unix::fs::symlink(&blob, &link).unwrap();
    }
    let mut victims = Vec::new();
    for (name, planted) in [
        ("victim_bak", "meta/stats.json.bak"),
        ("victim_norm", "norm_stats.json"),
    ] {
        let victim = d.join(name);
        fs_err::write(&victim, name).unwrap();
        std::os::unix::fs::symlink(&victim, root.join(planted)).unwrap();
        victims.push((victim, name.as_bytes().to_vec()));
    }
    for e in fs_err::read_dir(&blobs).unwrap().flatten() {
        victims.push((e.path(), fs_err::read(e.path()).unwrap()));
    }
    (root, victims)
}

#[test]
fn every_command_reads_a_dataset_of_links_and_writes_through_none() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (linked, victims) = linked_copy(d);
    let out = d.join("out");
    let o = |name: &str| out.join(name);
    let commands: Vec<Vec<String>> = vec![
        vec!["info".into()],
        vec!["filter".into(), "--episodes".into(), "0,2".into()],
        vec!["split".into(), "--splits".into(), "a=0.5,b=0.5".into()],
        vec!["trim".into(), "--frames".into(), "1=2..12".into()],
        vec![
            "features".into(),
            "--remove".into(),
            "observation.state".into(),
        ],
        vec![
            "reencode".into(),
            "--codec".into(),
            "h264".into(),
            "--preset".into(),
            "ultrafast".into(),
        ],
        vec!["to-v21".into()],
    ];
    for c in &commands {
        let mut args: Vec<&str> = vec![&c[0], s(&linked)];
        args.extend(c[1..].iter().map(String::as_str));
        let target = o(&c[0]);
        if c[0] != "info" {
            args.extend(["--out", s(&target)]);
        }
        dataset(&args, 0, &[]);
        if target.exists() {
            let links: Vec<_> = walk(&target)
                .into_iter()
                .filter(|p| p.is_symlink())
                .collect();
            assert!(links.is_empty(), "{}: links in the output: {links:?}", c[0]);
        }
    }
    dataset(
        &[
            "merge",
            s(&linked),
            s(lerobot_written()),
            "--out",
            s(&o("merge")),
        ],
        0,
        &[],
    );
    // In place: the planted links are replaced by files, their targets untouched.
    dataset(&["stats", s(&linked), "--norm-stats"], 0, &["stats.json"]);
    for (victim, bytes) in &victims {
        assert_eq!(
            &fs_err::read(victim).unwrap(),
            bytes,
            "{} changed",
            victim.display()
        );
    }
    for planted in ["meta/stats.json", "meta/stats.json.bak", "norm_stats.json"] {
        let p = linked.join(planted);
        assert!(p.is_file() && !p.is_symlink(), "{planted}");
    }
    // A linked folder on the way to what `dataset stats` writes: refused, nothing written.
    let moved = d.join("meta_elsewhere");
    fs_err::rename(linked.join("meta"), &moved).unwrap();
    std::os::unix::fs::symlink(&moved, linked.join("meta")).unwrap();
    let before = dexjoco_testkit::file_tree(&moved);
    dataset(
        &["stats", s(&linked)],
        1,
        &["snapshot/meta", "symbolic link"],
    );
    assert_eq!(dexjoco_testkit::file_tree(&moved), before);
    nothing_partial(d);
}

/// An eval folder of one rollout: the click_mouse sample's episode with `record` as its
/// `episode.json`.
fn eval_folder(d: &Path, record: &str) -> PathBuf {
    let root = d.join("eval");
    let _ = fs_err::remove_dir_all(&root);
    let episode = root.join("click_mouse/episode_000000");
    let sample =
        dexjoco_testkit::workspace_root().join("datasets/demos/click_mouse/episode_000000");
    dexjoco_formats::fs::copy_tree(&sample, &episode).unwrap();
    fs_err::write(episode.join("episode.json"), record).unwrap();
    root
}

#[test]
fn tampered_evaluation_records_are_named_by_convert() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let rows = 522;
    let valid = serde_json::json!({
        "task": "click_mouse", "success": true, "success_step": 500,
        "steps": rows - 22, "warmup_steps": 22, "subtasks": []
    });
    let convert = |root: &Path, out: &Path| {
        dexjoco()
            .args(["-q", "convert"])
            .arg(root)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let ok = d.join("ok");
    let o = convert(&eval_folder(d, &valid.to_string()), &ok);
    assert_eq!(o.status.code(), Some(0), "{}", said(&o));
    for (field, value) in [
        ("steps", serde_json::json!(1e15)),
        ("steps", serde_json::json!(1_000_000_000_000_000u64)),
        ("warmup_steps", serde_json::json!(u64::MAX)),
        ("steps", serde_json::json!(-5)),
        ("success", serde_json::json!("yes")),
    ] {
        let mut r = valid.clone();
        r[field] = value.clone();
        let out = d.join("bad");
        let started = std::time::Instant::now();
        let o = convert(&eval_folder(d, &r.to_string()), &out);
        let text = said(&o);
        assert_eq!(o.status.code(), Some(1), "{field} = {value}: {text}");
        assert!(
            text.contains("episode.json") && text.contains(&format!("field '{field}'")),
            "{field} = {value}: {text}"
        );
        assert!(
            started.elapsed().as_secs() < 60,
            "{field}: {:?}",
            started.elapsed()
        );
        assert!(!out.exists(), "{field}");
    }
    let o = convert(&eval_folder(d, "{\"task\": \"click_mo"), &d.join("bad"));
    let text = said(&o);
    assert!(
        o.status.code() == Some(1)
            && text.contains("not valid JSON")
            && !text.contains("cannot tell"),
        "{text}"
    );
}

#[test]
fn a_resume_redoes_the_attempts_its_log_cannot_vouch_for() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("gen");
    let generate = || {
        succeeds(
            dexjoco()
                .args(["generate", "--task", "click_mouse", "--count", "2", "--out"])
                .arg(&out),
        )
    };
    generate();
    let task = out.join("click_mouse");
    let first = dexjoco_testkit::file_tree(&task.join("episode_000000"));
    // A record with an empty reset (the figure indexed it): redone, named.
    let record = task.join(".attempts/attempt_000000.json");
    let mut r: Value = serde_json::from_str(&fs_err::read_to_string(&record).unwrap()).unwrap();
    r["reset"] = serde_json::json!([]);
    fs_err::write(&record, r.to_string()).unwrap();
    let o = generate();
    assert!(
        said(&o).contains("attempt_000000.json' is not trusted"),
        "{}",
        said(&o)
    );
    assert_eq!(
        dexjoco_testkit::file_tree(&task.join("episode_000000")),
        first
    );
    // An episode folder deleted while its record stays: made again, the count met.
    fs_err::remove_dir_all(task.join("episode_000001")).unwrap();
    let o = generate();
    assert!(said(&o).contains("missing or incomplete"), "{}", said(&o));
    assert!(task.join("episode_000001/replay.zarr").is_dir());
    let report: Value =
        serde_json::from_str(&fs_err::read_to_string(task.join("generate_report.json")).unwrap())
            .unwrap();
    assert_eq!(report["episodes"], serde_json::json!([0, 1]), "{report}");
    // A link planted in the folder (its resume log moved elsewhere): refused, nothing
    // written there.
    let elsewhere = dir.path().join("elsewhere");
    fs_err::rename(task.join(".attempts"), &elsewhere).unwrap();
    std::os::unix::fs::symlink(&elsewhere, task.join(".attempts")).unwrap();
    let before = dexjoco_testkit::file_tree(&elsewhere);
    let o = dexjoco()
        .args(["generate", "--task", "click_mouse", "--count", "3", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let text = said(&o);
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(text.contains(".attempts' is a symbolic link"), "{text}");
    assert_eq!(dexjoco_testkit::file_tree(&elsewhere), before);
}
