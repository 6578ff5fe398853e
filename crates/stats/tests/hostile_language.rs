//! Hostile language-evaluation tables, made by mutating a valid tidy CSV: values
//! replaced by hostile text, lines removed, repeated, swapped, inserted or byte-edited.
//! Loading and analysing never panics or hangs, and every rejection names the file and
//! the field (column, row or line).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use dexjoco_stats::{LanguageInput, LanguageOptions, LanguageReport};
use dexjoco_testkit::hostile::{apply_bytes, apply_lines, byte_edits, line_edits, run_cases};
use proptest::prelude::*;

static ACCEPTED: AtomicUsize = AtomicUsize::new(0);
static REJECTED: AtomicUsize = AtomicUsize::new(0);
static CASE: AtomicUsize = AtomicUsize::new(0);

fn valid_csv() -> String {
    let mut s = String::from("instruction,expected,seed,episode,output,prompt\n");
    for (i, (label, expected)) in [("two", "2"), ("1+1", "2"), ("three", "3")]
        .into_iter()
        .enumerate()
    {
        for seed in 0..2 {
            for ep in 0..4 {
                let output = match (i + seed + ep) % 4 {
                    0 => expected.to_owned(),
                    1 => String::new(),
                    2 => "none".into(),
                    _ => format!("{}", ep + 1),
                };
                let _ = writeln!(s, "{label},{expected},{seed},{ep},{output},enter {label}");
            }
        }
    }
    s
}

fn check(dir: &Path, bytes: &[u8]) -> Result<(), String> {
    let path: PathBuf = dir.join(format!(
        "trials-{}.csv",
        CASE.fetch_add(1, Ordering::Relaxed)
    ));
    fs_err::write(&path, bytes).unwrap();
    let result = match LanguageInput::load(&path) {
        Ok(input) => {
            ACCEPTED.fetch_add(1, Ordering::Relaxed);
            let report = LanguageReport::analyze(&input, LanguageOptions::default());
            let _ = report.to_markdown();
            Ok(())
        }
        Err(e) => {
            REJECTED.fetch_add(1, Ordering::Relaxed);
            let msg = e.to_string();
            let named = ["column", "row", "line", "field"]
                .iter()
                .any(|w| msg.contains(w));
            if msg.contains(&path.display().to_string()) && named {
                Ok(())
            } else {
                Err(format!("a rejection without file and field: {msg}"))
            }
        }
    };
    fs_err::remove_file(&path).unwrap();
    result
}

#[test]
fn mutated_evaluation_tables_are_rejected_by_name_never_a_panic() {
    let shm = Path::new("/dev/shm");
    let tmp = Arc::new(if shm.is_dir() {
        tempfile::tempdir_in(shm).unwrap()
    } else {
        tempfile::tempdir().unwrap()
    });
    let csv = valid_csv();
    check(tmp.path(), csv.as_bytes()).unwrap();
    let strategy = (line_edits(4), prop::option::weighted(0.2, byte_edits(3)));
    let took = run_cases(
        "language-eval csv",
        2000,
        strategy,
        move |(lines, bytes)| {
            let text = apply_lines(&csv, &lines);
            let data = match &bytes {
                Some(b) => apply_bytes(text.as_bytes(), b),
                None => text.into_bytes(),
            };
            check(tmp.path(), &data)
        },
    );
    assert!(took.as_secs() < 120, "{took:?}");
    assert!(
        ACCEPTED.load(Ordering::Relaxed) > 50,
        "some mutated tables load"
    );
    assert!(REJECTED.load(Ordering::Relaxed) > 50, "some are rejected");
}
