//! Hostile evaluation and replay records (`episode.json` written by `eval`, `replay.json`
//! by `augment`), made by mutating valid ones: what `convert` reads of them never panics
//! or hangs, a record that reads has only bounded step counts (so nothing is built per
//! step of a claimed 10^15), and a record that claims to be `eval`'s but is malformed is
//! refused naming the file and the field, never read as a plain recording.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use dexjoco_formats::dataset::language::subtask_rows;
use dexjoco_formats::raw::{MAX_RECORD_STEPS, read_eval_rollout, read_replay_label};
use dexjoco_testkit::hostile::{apply_bytes, apply_json, byte_edits, json_edits, run_cases};
use proptest::prelude::*;
use serde_json::{Value, json};

fn eval_record() -> Value {
    json!({
        "task": "click_mouse",
        "episode": 3,
        "seed": 0,
        "success": true,
        "success_step": 120,
        "steps": 121,
        "warmup_steps": 30,
        "subtasks": [
            {"id": "push_mouse", "text": "push the mouse", "start": 0, "end": 80},
            {"id": "click", "text": "click it", "start": 81, "end": 120}
        ]
    })
}

fn replay_record() -> Value {
    json!({
        "success": true,
        "first_success": 200,
        "steps": 240,
        "recorded_steps": 240,
        "extended": false,
        "flags": [],
        "sample": {"seed": 7},
        "subtasks": [{"id": "lift", "text": "", "start": 0, "end": 150}]
    })
}

static READ: AtomicUsize = AtomicUsize::new(0);
static REFUSED: AtomicUsize = AtomicUsize::new(0);

/// Reads `bytes` as `name` in a folder of its own, with `read`; checks what it gives.
fn check(dir: &Path, name: &str, bytes: &[u8]) -> Result<(), String> {
    fs_err::create_dir_all(dir).unwrap();
    let path = dir.join(name);
    fs_err::write(&path, bytes).unwrap();
    let label = if name == "episode.json" {
        read_eval_rollout(dir).map(|r| r.map(|r| (r.steps, r.success_step, r.subtasks)))
    } else {
        read_replay_label(dir).map(|l| l.map(|l| (l.steps, l.first_success, l.subtasks)))
    };
    let result = match label {
        Ok(Some((steps, success, spans))) => {
            READ.fetch_add(1, Ordering::Relaxed);
            if steps as u64 > MAX_RECORD_STEPS {
                return Err(format!("{steps} steps read"));
            }
            if name == "episode.json" && success.is_some_and(|s| s > steps) {
                return Err(format!("success step {success:?} past {steps} steps"));
            }
            // What convert builds per record: its subtask rows, in the spans' time.
            let rows = subtask_rows(&spans, 0, steps.max(1));
            (rows.len() <= 2 * spans.len() + 1)
                .then_some(())
                .ok_or_else(|| format!("{} rows from {} spans", rows.len(), spans.len()))
        }
        Ok(None) => Ok(()),
        Err(e) => {
            REFUSED.fetch_add(1, Ordering::Relaxed);
            let msg = e.to_string();
            msg.contains(&path.display().to_string())
                .then_some(())
                .ok_or_else(|| format!("a refusal without the file: {msg}"))
        }
    };
    fs_err::remove_dir_all(dir).unwrap();
    result
}

#[test]
fn mutated_records_are_read_bounded_or_refused_by_name() {
    let tmp = Arc::new(tempfile::tempdir().unwrap());
    let docs = [
        ("episode.json", eval_record()),
        ("replay.json", replay_record()),
    ];
    for (name, d) in &docs {
        check(&tmp.path().join("valid"), name, d.to_string().as_bytes()).unwrap();
    }
    let case = Arc::new(AtomicUsize::new(0));
    let strategy = (
        0..docs.len(),
        json_edits(3),
        prop::option::weighted(0.2, byte_edits(3)),
    );
    let took = run_cases("records", 3000, strategy, move |(d, edits, bytes)| {
        let (name, doc) = &docs[d];
        let text = apply_json(doc, &edits).to_string();
        let data = match &bytes {
            Some(e) => apply_bytes(text.as_bytes(), e),
            None => text.into_bytes(),
        };
        let dir = tmp
            .path()
            .join(case.fetch_add(1, Ordering::Relaxed).to_string());
        check(&dir, name, &data)
    });
    assert!(took.as_secs() < 60, "{took:?}");
    assert!(
        READ.load(Ordering::Relaxed) > 100,
        "some mutated records read"
    );
    assert!(REFUSED.load(Ordering::Relaxed) > 100, "some are refused");
}

/// The cases `convert` once read wrongly: a step count of 10^15 (its subtask rows were
/// built per step: a hang), a warm-up of 2^64-1 (wrapped, then a slice past the end), a
/// negative step count and a verdict of "yes" (read as a plain recording, no label), a
/// record that is not JSON (named "cannot tell the task").
#[test]
fn the_records_convert_once_trusted_are_refused_naming_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    let mut cases: Vec<(Value, &str)> = Vec::new();
    for (field, value, named) in [
        ("steps", json!(1_000_000_000_000_000u64), "steps"),
        ("warmup_steps", json!(u64::MAX), "warmup_steps"),
        ("steps", json!(-5), "steps"),
        ("success", json!("yes"), "success"),
        ("success_step", json!(400), "success_step"),
    ] {
        let mut v = eval_record();
        v[field] = value;
        cases.push((v, named));
    }
    for (k, (v, field)) in cases.iter().enumerate() {
        let dir = tmp.path().join(k.to_string());
        fs_err::create_dir_all(&dir).unwrap();
        fs_err::write(dir.join("episode.json"), v.to_string()).unwrap();
        let e = read_eval_rollout(&dir).unwrap_err().to_string();
        assert!(
            e.contains("episode.json") && e.contains(&format!("field '{field}'")),
            "{v}: {e}"
        );
    }
    let dir = tmp.path().join("not-json");
    fs_err::create_dir_all(&dir).unwrap();
    fs_err::write(dir.join("episode.json"), b"{\"success\": tru").unwrap();
    let e = read_eval_rollout(&dir).unwrap_err().to_string();
    assert!(e.contains("not valid JSON"), "{e}");
    // A record of another program (no verdict, no steps) is no rollout.
    fs_err::write(dir.join("episode.json"), b"{\"subtasks\": []}").unwrap();
    assert!(read_eval_rollout(&dir).unwrap().is_none());
}
