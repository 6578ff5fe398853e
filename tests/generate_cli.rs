//! The `generate` command end to end on click_mouse from its shipped sample: the same
//! bytes whatever `-j`, a run killed with SIGKILL continues to the same bytes, a larger
//! `--count` goes on from a finished run, and a folder of other settings is refused
//! unless `--overwrite`. The episodes written are read back as raw episodes of the task.

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

mod common;

/// `generate --task click_mouse` into `work`/generate with `args`.
fn generate(work: &Path, args: &[&str]) -> Command {
    let mut c = common::dexjoco();
    c.env("DEXJOCO_LOG", "warn")
        .arg("-q")
        .arg("--work-dir")
        .arg(work)
        .args(["generate", "--task", "click_mouse"])
        .args(args);
    c
}

fn ok(out: Output) -> Output {
    assert!(out.status.success(), "{}", common::said(&out));
    out
}

/// The run's files, without the one whose bytes depend on the machine (its timing) and
/// the attempts set aside past the run's end (`.surplus/`).
fn tree(work: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut t = dexjoco_testkit::file_tree(&work.join("generate/click_mouse"));
    assert!(t.remove(dexjoco_generate::TIMES_FILE).is_some());
    t.retain(|k, _| !k.starts_with(".surplus/"));
    t
}

/// Asserts two runs' files are the same, naming the files that differ.
fn same(a: &BTreeMap<String, Vec<u8>>, b: &BTreeMap<String, Vec<u8>>, what: &str) {
    let differ: Vec<&String> = a
        .keys()
        .chain(b.keys())
        .filter(|k| a.get(*k) != b.get(*k))
        .collect();
    assert!(differ.is_empty(), "{what}: these differ: {differ:?}");
}

fn episodes(t: &BTreeMap<String, Vec<u8>>) -> Vec<&str> {
    t.keys()
        .filter(|k| k.ends_with("/generate.json") && k.starts_with("episode_"))
        .map(|k| &k[..14])
        .collect()
}

#[test]
fn generate_is_deterministic_across_workers_and_resumes_after_sigkill() {
    let tmp = tempfile::tempdir().unwrap();
    let (one, two, killed) = (
        tmp.path().join("one"),
        tmp.path().join("two"),
        tmp.path().join("killed"),
    );
    let count = ["--count", "4", "--seed", "7"];
    ok(generate(&one, &count).arg("-j1").output().unwrap());
    ok(generate(&two, &count).arg("-j2").output().unwrap());
    let a = tree(&one);
    assert_eq!(episodes(&a).len(), 4, "{:?}", a.keys().collect::<Vec<_>>());
    same(&a, &tree(&two), "-j 1 and -j 2 write the same bytes");

    // Each episode is a raw episode of the task, with its provenance.
    let dir = one.join("generate/click_mouse").join(episodes(&a)[0]);
    let ep = dexjoco_formats::read_episode(&dir, dexjoco_core::TaskSet::builtin()).unwrap();
    assert_eq!(ep.task, "click_mouse");
    let record: serde_json::Value =
        serde_json::from_slice(&fs_err::read(dir.join("generate.json")).unwrap()).unwrap();
    assert_eq!(record["success"], true);
    let provenance = record["provenance"].as_array().unwrap();
    assert_eq!(provenance.len(), 2, "push_mouse and click: {record}");
    assert_eq!(provenance[0]["subtask"], "push_mouse");
    assert!(
        provenance[0]["source"]
            .as_str()
            .unwrap()
            .starts_with("episode_0000")
    );
    // The reset differs from the source's: the segments were carried somewhere new.
    assert_ne!(provenance[0]["source_object"], provenance[0]["new_object"]);

    // Killed with SIGKILL once two attempts are committed, then rerun: the same bytes.
    let mut child = generate(&killed, &count).arg("-j1").spawn().unwrap();
    let attempts = killed.join("generate/click_mouse/.attempts");
    let until = Instant::now() + Duration::from_secs(120);
    while fs_err::read_dir(&attempts).map_or(0, |d| d.count()) < 2 {
        assert!(Instant::now() < until, "no attempt committed in 120 s");
        assert!(child.try_wait().unwrap().is_none(), "ended before the kill");
        std::thread::sleep(Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(
        !killed
            .join("generate/click_mouse/generate_report.json")
            .exists(),
        "killed before the end"
    );
    // As a kill mid-write leaves it: an atomic write's temporary file.
    fs_err::write(
        attempts.join(".attempt_000003.json.partial-x1y2z3"),
        b"{\"att",
    )
    .unwrap();
    ok(generate(&killed, &count).arg("-j2").output().unwrap());
    same(
        &a,
        &tree(&killed),
        "a killed run continues to the same bytes",
    );
}

#[test]
fn generate_shards_and_count_changes_write_what_one_run_writes() {
    let tmp = tempfile::tempdir().unwrap();
    let one = tmp.path().join("one");
    let count = ["--count", "4", "--seed", "7"];
    ok(generate(&one, &count).arg("-j1").output().unwrap());
    let a = tree(&one);
    // Two shards at once into one folder, then the finalize step: the same bytes.
    let sharded = tmp.path().join("sharded");
    let shards: Vec<_> = ["0/2", "1/2"]
        .iter()
        .map(|s| {
            generate(&sharded, &count)
                .args(["-j1", "--shard", s])
                .spawn()
                .unwrap()
        })
        .collect();
    for mut s in shards {
        assert!(s.wait().unwrap().success());
    }
    assert!(
        !sharded
            .join("generate/click_mouse/generate_report.json")
            .exists(),
        "a shard writes no report"
    );
    ok(generate(&sharded, &count).output().unwrap());
    same(
        &a,
        &tree(&sharded),
        "shards and their finalize step write the same bytes",
    );

    // A larger --count goes on from there: the first four episodes stay as they were.
    let more = ["--count", "6", "--seed", "7"];
    let out = ok(generate(&one, &more).output().unwrap());
    let b = tree(&one);
    assert_eq!(
        episodes(&b).len(),
        6,
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    for (k, v) in &a {
        if k.starts_with("episode_") {
            assert_eq!(b.get(k), Some(v), "{k} was kept");
        }
    }
    // Back to --count 4: the folder of a --count 4 run again, the two others set aside,
    // and put back (not made again) by a run that needs them.
    ok(generate(&one, &count).output().unwrap());
    same(&a, &tree(&one), "a smaller --count sets the surplus aside");
    let surplus = one.join("generate/click_mouse/.surplus");
    assert_eq!(
        fs_err::read_dir(surplus.join(".attempts")).unwrap().count(),
        2
    );
    let out = ok(generate(&one, &more).output().unwrap());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("0 made now"), "{text}");
    same(&b, &tree(&one), "the surplus put back");
}

#[test]
fn generate_refuses_a_folder_of_other_settings_unless_overwrite() {
    let tmp = tempfile::tempdir().unwrap();
    ok(generate(tmp.path(), &["--count", "1", "--seed", "1"])
        .output()
        .unwrap());
    let other = generate(tmp.path(), &["--count", "1", "--seed", "2"])
        .output()
        .unwrap();
    assert_eq!(other.status.code(), Some(1));
    let err = String::from_utf8_lossy(&other.stderr);
    assert!(
        err.contains("other settings")
            && err.contains("seed differs")
            && err.contains("--overwrite"),
        "{err}"
    );
    ok(
        generate(tmp.path(), &["--count", "1", "--seed", "2", "--overwrite"])
            .output()
            .unwrap(),
    );
    let settings: serde_json::Value = serde_json::from_slice(
        &fs_err::read(
            tmp.path()
                .join("generate/click_mouse/generate_settings.json"),
        )
        .unwrap(),
    )
    .unwrap();
    assert_eq!(settings["seed"], 2);

    // A source of another task is left out and named; no usable source: exit 1.
    let pinch = dexjoco_testkit::workspace_root().join("datasets/demos/pinch_tongs");
    let out = generate(&tmp.path().join("w2"), &["--count", "1"])
        .arg(&pinch)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("source left out")
            && err.contains("an episode of 'pinch_tongs', not 'click_mouse'"),
        "{err}"
    );
}

#[test]
fn generate_dry_run_estimates_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = ok(
        generate(tmp.path(), &["--count", "50", "--dry-run", "--pilot", "3"])
            .output()
            .unwrap(),
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("of 3 attempt(s) succeeded"), "{text}");
    assert!(text.contains("--count 50 expects about"), "{text}");
    assert!(
        !tmp.path().join("generate").exists(),
        "a dry run writes nothing"
    );
}

/// A source whose recording ends before its success (as a recording made with another
/// MuJoCo may: the reason for augment's `--extend-steps`) is left out with the strict
/// replay, and accepted with the default extension, named in the report with the steps
/// it went on.
#[test]
fn a_source_that_succeeds_only_past_its_end_is_extended_and_named() {
    let tmp = tempfile::tempdir().unwrap();
    let spec = dexjoco_core::TaskSpec::builtin("click_mouse").unwrap();
    let sample =
        dexjoco_testkit::workspace_root().join("datasets/demos/click_mouse/episode_000000");
    let mut ep = dexjoco_formats::raw::read_raw_episode(&sample, spec)
        .unwrap()
        .episode;
    let cut = ep.len() - 3;
    for a in ep.arrays.values_mut() {
        let w = a.width();
        *a = dexjoco_core::FrameArray::new(w, a.as_slice()[..cut * w].to_vec()).unwrap();
    }
    let source = tmp.path().join("late/click_mouse/episode_000000");
    dexjoco_formats::raw::write_raw_episode(&source, &ep, spec).unwrap();
    let late = tmp.path().join("late/click_mouse");
    let strict = generate(tmp.path(), &["--count", "1", "--extend-steps", "0"])
        .arg(&late)
        .output()
        .unwrap();
    let text = common::said(&strict);
    assert_eq!(strict.status.code(), Some(1), "{text}");
    assert!(text.contains("never ends when it is replayed"), "{text}");
    ok(generate(tmp.path(), &["--count", "1"])
        .arg(&late)
        .output()
        .unwrap());
    let dir = tmp.path().join("generate/click_mouse");
    let report: serde_json::Value =
        serde_json::from_slice(&fs_err::read(dir.join("generate_report.json")).unwrap()).unwrap();
    let extended = &report["sources_extended"];
    assert_eq!(extended[0][0], "episode_000000", "{report}");
    let steps = extended[0][1].as_u64().unwrap();
    assert!((1..=30).contains(&steps), "{report}");
    let md = fs_err::read_to_string(dir.join("generate_report.md")).unwrap();
    assert!(
        md.contains(&format!("episode_000000: {steps} step(s) past its end")),
        "{md}"
    );
}
