//! Hostile task specs, made by mutating the shipped ones: TOML values replaced, removed,
//! added or repeated (wrong types, extremes, NaN, unknown keys), and lines removed,
//! repeated, swapped or byte-edited. Parsing and checking never panics or hangs, and
//! every rejection names the file and the field (a key path, or the line and column).

use std::sync::atomic::{AtomicUsize, Ordering};

use dexjoco_core::TaskSpec;
use dexjoco_testkit::hostile::{apply_json, apply_lines, json_edits, line_edits, run_cases};
use proptest::prelude::*;

const FILE: &str = "hostile/task_spec.toml";

static ACCEPTED: AtomicUsize = AtomicUsize::new(0);
static REJECTED: AtomicUsize = AtomicUsize::new(0);

fn shipped() -> Vec<String> {
    let dir = dexjoco_testkit::workspace_root().join("schemas/tasks");
    let mut paths: Vec<_> = fs_err::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    paths.sort();
    assert_eq!(paths.len(), 11);
    paths
        .iter()
        .map(|p| fs_err::read_to_string(p).unwrap())
        .collect()
}

fn check(text: &str) -> Result<(), String> {
    match TaskSpec::from_toml_str(text, FILE) {
        Ok(spec) => {
            ACCEPTED.fetch_add(1, Ordering::Relaxed);
            // What the stages ask of a spec works on any spec that passed.
            spec.evaluation_order().map_err(|e| e.to_string())?;
            let _ = spec.state_layout();
            let _ = spec.scene_names();
            Ok(())
        }
        Err(e) => {
            REJECTED.fetch_add(1, Ordering::Relaxed);
            let msg = e.to_string();
            if msg.contains(FILE) && (msg.contains("field") || msg.contains("line ")) {
                Ok(())
            } else {
                Err(format!("a rejection without file and field: {msg}"))
            }
        }
    }
}

#[test]
fn mutated_task_specs_are_rejected_by_name_never_a_panic() {
    let texts = shipped();
    for t in &texts {
        check(t).unwrap();
    }
    let docs: Vec<serde_json::Value> = texts
        .iter()
        .map(|t| serde_json::to_value(toml::from_str::<toml::Table>(t).unwrap()).unwrap())
        .collect();
    let values = {
        let docs = docs.clone();
        (0..docs.len(), json_edits(3)).prop_filter_map("not TOML", move |(b, e)| {
            let v = apply_json(&docs[b], &e);
            let table: toml::Table = serde_json::from_value(v).ok()?;
            toml::to_string(&table).ok()
        })
    };
    let took = run_cases("task spec values", 1500, values, |text| check(&text));
    let lines = (0..texts.len(), line_edits(3));
    let took = took
        + run_cases("task spec lines", 1500, lines, move |(b, e)| {
            check(&apply_lines(&texts[b], &e))
        });
    assert!(took.as_secs() < 120, "{took:?}");
    assert!(
        ACCEPTED.load(Ordering::Relaxed) > 50,
        "some mutated specs pass"
    );
    assert!(REJECTED.load(Ordering::Relaxed) > 50, "some are rejected");
}
