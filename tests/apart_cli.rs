//! Issue #34 through the binary: no command writes into, over or around what it reads,
//! nothing from the input becomes a path, the same checks apply whichever door an
//! episode comes in by, and a bad success marker is one bad folder.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Output;

use common::dexjoco;
use dexjoco_core::{Episode, TaskSpec};
use dexjoco_formats::{EpisodeContainer, EpisodeMeta, mcap::McapLog};

/// Every path under `root` with its size and modification time: what a run must leave
/// as it was.
fn tree(root: &Path) -> BTreeMap<PathBuf, (u64, std::time::SystemTime)> {
    let mut out = BTreeMap::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for e in fs_err::read_dir(&dir).unwrap() {
            let e = e.unwrap();
            let meta = fs_err::symlink_metadata(e.path()).unwrap();
            if meta.is_dir() {
                stack.push(e.path());
            }
            out.insert(e.path(), (meta.len(), meta.modified().unwrap()));
        }
    }
    out
}

fn run(args: &[&str], cwd: &Path) -> Output {
    dexjoco().args(args).current_dir(cwd).output().unwrap()
}

fn text(o: &Output) -> String {
    format!(
        "exit {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn sample(rel: &str) -> PathBuf {
    dexjoco_testkit::workspace_root().join("datasets").join(rel)
}

/// A command's input (copied under `root/in/<name>`) and how to run it with an output.
struct Case {
    name: &'static str,
    /// The input, under `in/` (copied from the sample data).
    from: &'static str,
    /// The command's arguments for input `IN` and output `OUT`.
    args: &'static [&'static str],
}

const CASES: &[Case] = &[
    Case {
        name: "stats-language",
        from: "examples/language-eval",
        args: &["stats", "--language-eval", "IN", "--out", "OUT"],
    },
    Case {
        name: "stats-success",
        from: "examples/success-table",
        args: &["stats", "--success-table", "IN", "--out", "OUT"],
    },
    Case {
        name: "stats-dataset",
        from: "demos/click_mouse",
        args: &["stats", "--dataset", "IN", "--out", "OUT"],
    },
    Case {
        name: "ingest",
        from: "demos/click_mouse",
        args: &["ingest", "IN", "--out", "OUT"],
    },
    Case {
        name: "augment",
        from: "demos/click_mouse",
        args: &[
            "augment",
            "IN",
            "--out",
            "OUT",
            "--size",
            "32",
            "--max-frames",
            "2",
        ],
    },
    Case {
        name: "convert",
        from: "demos/click_mouse",
        args: &["convert", "IN", "--out", "OUT"],
    },
    Case {
        name: "export",
        from: "demos/click_mouse",
        args: &["export", "--to", "mcap", "IN", "--out", "OUT"],
    },
    Case {
        name: "scripted",
        from: "demos/click_mouse",
        args: &[
            "scripted",
            "--task",
            "click_mouse",
            "--scene-dir",
            "IN",
            "--out",
            "OUT",
        ],
    },
    Case {
        name: "render",
        from: "demos/click_mouse",
        args: &[
            "render",
            "--task",
            "click_mouse",
            "--scene-dir",
            "IN",
            "--out",
            "OUT",
        ],
    },
    Case {
        name: "cameras",
        from: "demos/click_mouse",
        args: &[
            "cameras",
            "--task",
            "click_mouse",
            "--scene-dir",
            "IN",
            "--out",
            "OUT",
        ],
    },
];

#[test]
fn no_command_writes_into_over_or_around_what_it_reads() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    for case in CASES {
        let input = root.join("in").join(case.name).join("click_mouse");
        dexjoco_formats::fs::copy_tree(&sample(case.from), &input).unwrap();
    }
    // A link to an input: an output reached through it is the input all the same.
    fs_err::create_dir(root.join("link")).unwrap();
    std::os::unix::fs::symlink(
        root.join("in/stats-dataset/click_mouse"),
        root.join("link/click_mouse"),
    )
    .unwrap();
    let before = tree(root);
    for case in CASES {
        let input = format!("in/{}/click_mouse", case.name);
        let outputs = [
            (input.clone(), "is"),
            (format!("{input}/out"), "lies inside"),
            (format!("in/{}", case.name), "holds"),
        ];
        for (out, how) in outputs {
            let args: Vec<&str> = case
                .args
                .iter()
                .map(|a| match *a {
                    "IN" => input.as_str(),
                    "OUT" => out.as_str(),
                    a => a,
                })
                .collect();
            let o = run(&args, root);
            let said = text(&o);
            assert_eq!(
                o.status.code(),
                Some(2),
                "{} --out {out}: {said}",
                case.name
            );
            assert!(
                said.contains(&format!("the output '{out}' {how} the input '{input}'")),
                "{} --out {out}: {said}",
                case.name
            );
            assert_eq!(
                tree(root),
                before,
                "{} --out {out} wrote: {said}",
                case.name
            );
        }
    }
    let o = run(
        &[
            "stats",
            "--dataset",
            "link/click_mouse",
            "--out",
            "in/stats-dataset/click_mouse/x",
        ],
        root,
    );
    let said = text(&o);
    assert_eq!(o.status.code(), Some(2), "{said}");
    assert!(
        said.contains("lies inside the input 'link/click_mouse'"),
        "{said}"
    );
    assert_eq!(tree(root), before);
    // Apart, the same command runs (and writes only its output).
    let o = run(
        &["stats", "--dataset", "link/click_mouse", "--out", "apart"],
        root,
    );
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(root.join("apart/dataset/dataset_stats.json").is_file());
}

/// The click_mouse sample demonstration, with its arrays cut to `frames`.
fn good_episode(frames: usize) -> (Episode, &'static TaskSpec) {
    let spec = TaskSpec::builtin("click_mouse").unwrap();
    let tasks = dexjoco_core::TaskSet::builtin();
    let mut ep =
        dexjoco_formats::read_episode(&sample("demos/click_mouse/episode_000000"), tasks).unwrap();
    for a in ep.arrays.values_mut() {
        let rows: Vec<Vec<f64>> = a.rows().take(frames).map(<[f64]>::to_vec).collect();
        *a = dexjoco_core::FrameArray::from_rows(&rows).unwrap();
    }
    ep.cameras.clear();
    (ep, spec)
}

fn write_log(path: &Path, ep: &Episode, spec: &TaskSpec) {
    McapLog
        .write(path, ep, spec, &EpisodeMeta::default())
        .unwrap();
}

/// The paths a run added under `root`, other than its output folder `out` and that
/// folder's lock and staging siblings (`.<name>.lock`, `.<name>.partial-*`).
fn written_elsewhere(
    root: &Path,
    before: &BTreeMap<PathBuf, (u64, std::time::SystemTime)>,
    out: &Path,
) -> Vec<PathBuf> {
    let name = out.file_name().unwrap().to_string_lossy().into_owned();
    tree(root)
        .into_keys()
        .filter(|p| !before.contains_key(p) && !p.starts_with(out))
        .filter(|p| {
            let beside = p.parent() == out.parent()
                && p.file_name()
                    .is_some_and(|n| n.to_string_lossy().starts_with(&format!(".{name}.")));
            !beside
        })
        .collect()
}

/// MCAP logs under `root/logs` and raw folders under `root/raw/click_mouse`: a good
/// episode (`good`) and one per hostile episode id (`id<i>`); and a log whose task is a
/// path (`task.mcap`). Returns the hostile ids.
fn hostile_inputs(root: &Path, abs: &Path) -> Vec<String> {
    let (logs, raw) = (root.join("logs"), root.join("raw/click_mouse"));
    fs_err::create_dir_all(&logs).unwrap();
    let (good, spec) = good_episode(12);
    write_log(&logs.join("good.mcap"), &good, spec);
    raw_with_entry(&raw.join("good"), &good, "good");
    let hostile_ids = vec![
        "../../../x".to_owned(),
        abs.display().to_string(),
        "..".to_owned(),
        "a\0b".to_owned(),
        ".hidden".to_owned(),
        "x".repeat(10_000),
    ];
    for (i, id) in hostile_ids.iter().enumerate() {
        let mut ep = good.clone();
        ep.id = id.clone();
        write_log(&logs.join(format!("id{i}.mcap")), &ep, spec);
        raw_with_entry(&raw.join(format!("id{i}")), &good, id);
    }
    let mut ep = good.clone();
    ep.task = "../../x".into();
    write_log(&logs.join("task.mcap"), &ep, spec);
    hostile_ids
}

/// A raw episode folder carrying a store entry (`.dexjoco-ingest.json`) that gives the
/// episode `id`: the id a raw folder's reader takes.
fn raw_with_entry(dir: &Path, ep: &Episode, id: &str) {
    use dexjoco_formats::{ENTRY_FILE, ManifestEntry, SourceKind, Status};
    dexjoco_formats::raw::write_replay_zarr(dir, ep).unwrap();
    let entry = ManifestEntry {
        id: id.to_owned(),
        task: Some(ep.task.clone()),
        source: dir.to_path_buf(),
        source_kind: SourceKind::Raw,
        source_hash: "sha256:0".into(),
        length: ep.len(),
        status: Status::Ok,
        path: "click_mouse/episode_000000".into(),
        problems: Vec::new(),
        notes: Vec::new(),
    };
    fs_err::write(dir.join(ENTRY_FILE), serde_json::to_vec(&entry).unwrap()).unwrap();
}

#[test]
fn names_from_the_data_are_names_whichever_door_the_episode_comes_in_by() {
    let tmp = tempfile::tempdir().unwrap();
    // Deep, so that an escaping `..` would still land inside the temporary folder.
    let root = tmp.path().join("a/b/c");
    let abs = tmp.path().join("abs/x");
    let hostile_ids = hostile_inputs(&root, &abs);
    let augment = |input: &'static str, out: &'static str| {
        vec![
            "augment",
            input,
            "--out",
            out,
            "--dynamics",
            "--keep-failed",
            "--size",
            "32",
            "--max-frames",
            "2",
            "--replays",
            "1",
        ]
    };
    let doors: Vec<(&str, &str, Vec<&str>)> = vec![
        (
            "logs",
            "ingest",
            vec!["ingest", "logs", "--out", "out-ingest"],
        ),
        ("logs", "augment-logs", augment("logs", "out-augment-logs")),
        ("raw", "augment-raw", augment("raw", "out-augment-raw")),
        (
            "logs",
            "convert-logs",
            vec![
                "convert",
                "logs",
                "--out",
                "out-convert-logs",
                "--format",
                "diffusion-policy",
            ],
        ),
        (
            "raw",
            "convert-raw",
            vec![
                "convert",
                "raw",
                "--out",
                "out-convert-raw",
                "--format",
                "diffusion-policy",
            ],
        ),
        (
            "raw",
            "export",
            vec!["export", "--to", "mcap", "raw", "--out", "out-export"],
        ),
    ];
    for (input, door, args) in doors {
        let before = tree(tmp.path());
        let o = run(&args, &root);
        let said = text(&o);
        assert_eq!(o.status.code(), Some(3), "{door}: {said}");
        for i in 0..hostile_ids.len() {
            let named = if input == "logs" {
                format!("id{i}.mcap")
            } else {
                format!("click_mouse/id{i}")
            };
            assert!(said.contains(&named), "{door}: {named} not named: {said}");
        }
        if input == "logs" {
            assert!(said.contains("task.mcap"), "{door}: {said}");
        }
        assert!(
            said.contains("cannot be a file name") || said.contains("unsafe_name"),
            "{door}: {said}"
        );
        let out = root.join(format!("out-{door}"));
        assert!(
            out.exists(),
            "{door}: the good episode went through: {said}"
        );
        let stray = written_elsewhere(tmp.path(), &before, &out);
        assert!(
            stray.is_empty(),
            "{door} wrote outside its output: {stray:?}\n{said}"
        );
        assert!(!abs.exists() && !tmp.path().join("a/x").exists());
    }
    // The ingest store quarantines each with its reason.
    let manifest = fs_err::read_to_string(root.join("out-ingest/manifest.json")).unwrap();
    assert!(
        manifest.matches("unsafe_name").count() >= hostile_ids.len(),
        "{manifest}"
    );
}

#[test]
fn a_task_spec_or_a_convert_config_that_names_a_path_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let tasks = root.join("tasks");
    fs_err::create_dir_all(&tasks).unwrap();
    let spec = fs_err::read_to_string(
        dexjoco_testkit::workspace_root().join("schemas/tasks/click_mouse.toml"),
    )
    .unwrap();
    assert!(spec.contains("key = \"front\""), "{spec}");
    fs_err::write(
        tasks.join("click_mouse.toml"),
        spec.replacen("key = \"front\"", "key = \"../../x\"", 1),
    )
    .unwrap();
    let o = run(
        &["ingest", "logs", "--tasks-dir", "tasks", "--out", "out"],
        root,
    );
    let said = text(&o);
    assert_ne!(o.status.code(), Some(0), "{said}");
    assert!(
        said.contains("cameras[0].key") && said.contains("cannot be a file name"),
        "{said}"
    );
    assert!(!root.join("out").exists());

    let input = common::convert_input(root);
    fs_err::write(
        root.join("sel.toml"),
        "[default.cameras]\n\"../../x\" = \"front\"\n",
    )
    .unwrap();
    let before = tree(root);
    let args = [
        "convert",
        input.to_str().unwrap(),
        "--config",
        "sel.toml",
        "--out",
        "ds",
    ];
    let o = run(&args, root);
    let said = text(&o);
    assert_ne!(o.status.code(), Some(0), "{said}");
    assert!(
        said.contains("output camera name") && said.contains("sel.toml"),
        "{said}"
    );
    assert!(written_elsewhere(root, &before, &root.join("ds")).is_empty());
}

#[test]
fn a_frame_rate_that_is_nan_zero_or_infinite_is_refused_at_every_door() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let logs = root.join("logs");
    fs_err::create_dir_all(&logs).unwrap();
    let (good, spec) = good_episode(12);
    write_log(&logs.join("good.mcap"), &good, spec);
    for (name, fps) in [("nan", f64::NAN), ("zero", 0.0), ("inf", f64::INFINITY)] {
        let mut ep = good.clone();
        ep.fps = fps;
        ep.id = name.into();
        write_log(&logs.join(format!("{name}.mcap")), &ep, spec);
    }
    let args = [
        "augment",
        "logs",
        "--out",
        "aug",
        "--size",
        "32",
        "--max-frames",
        "2",
        "--replays",
        "1",
        "--keep-failed",
    ];
    let o = run(&args, root);
    let said = text(&o);
    assert_eq!(o.status.code(), Some(3), "{said}");
    for (name, why) in [
        ("nan", "frame rate NaN is not finite"),
        ("zero", "frame rate 0 is not positive"),
        ("inf", "frame rate inf is not finite"),
    ] {
        let line = said
            .lines()
            .find(|l| l.contains(&format!("{name}.mcap")))
            .unwrap_or_else(|| panic!("{name}.mcap not named: {said}"));
        assert!(line.contains(why) && line.contains("fps"), "{line}");
    }
    // No replay of them; the good one replayed at 30 fps.
    let replays: Vec<String> = fs_err::read_dir(root.join("aug/click_mouse"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(replays, ["episode_000000__r00"], "{said}");
    // Ingest says the same.
    let o = run(&["ingest", "logs", "--out", "store"], root);
    let said = text(&o);
    assert_eq!(o.status.code(), Some(3), "{said}");
    assert!(said.contains("frame rate inf is not finite"), "{said}");
}

#[test]
fn a_bad_success_marker_is_one_bad_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path();
    let runs = root.join("runs");
    dexjoco_formats::fs::copy_tree(&sample("examples/success-table"), &runs).unwrap();
    let bad = runs.join("policy-a/pick_bucket_seed0");
    fs_err::rename(
        bad.join("success_rate_16_50.txt"),
        bad.join("success_rate_99_50.txt"),
    )
    .unwrap();
    let o = run(
        &["stats", "--success-table", "runs", "--out", "out", "--json"],
        root,
    );
    let said = text(&o);
    assert_eq!(o.status.code(), Some(3), "{said}");
    assert!(
        said.contains("left out: 'runs/policy-a/pick_bucket_seed0'")
            && said.contains("99 successes out of 50 episodes"),
        "{said}"
    );
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let table = &json["success_table"];
    assert_eq!(
        table["left_out"][0]["path"],
        "runs/policy-a/pick_bucket_seed0"
    );
    // The other runs are in the table: pick_bucket's other seeds and every other task.
    let cells = table["cells"].as_array().unwrap();
    assert!(cells.len() > 10, "{table}");
    assert!(root.join("out/success-table/success_table.md").is_file());
}
