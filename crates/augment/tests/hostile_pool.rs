//! Hostile camera-pool files, made by mutating a valid one: JSON values replaced,
//! removed, added or repeated, and bytes edited. Loading never panics or hangs, a pool
//! that loads has only finite poses at a positive distance, and every rejection names
//! the file and the field (`rows[3][2]`).

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use dexjoco_augment::{CameraPool, builtin_pool};
use dexjoco_core::ArmSetup;
use dexjoco_testkit::hostile::{apply_bytes, apply_json, byte_edits, json_edits, run_cases};
use proptest::prelude::*;

static ACCEPTED: AtomicUsize = AtomicUsize::new(0);
static REJECTED: AtomicUsize = AtomicUsize::new(0);
static CASE: AtomicUsize = AtomicUsize::new(0);

fn check(dir: &Path, bytes: &[u8]) -> Result<(), String> {
    let path = dir.join(format!(
        "pool-{}.json",
        CASE.fetch_add(1, Ordering::Relaxed)
    ));
    fs_err::write(&path, bytes).unwrap();
    let result = match CameraPool::load(&path) {
        Ok(pool) => {
            ACCEPTED.fetch_add(1, Ordering::Relaxed);
            if pool.poses.is_empty()
                || pool.poses.iter().any(|p| {
                    !(p.azimuth.is_finite()
                        && p.elevation.is_finite()
                        && p.distance.is_finite()
                        && p.distance > 0.0)
                })
            {
                Err(format!(
                    "a pool with a bad pose was loaded: {:?}",
                    pool.poses
                ))
            } else {
                Ok(())
            }
        }
        Err(e) => {
            REJECTED.fetch_add(1, Ordering::Relaxed);
            let msg = e.to_string();
            if msg.contains(&path.display().to_string()) && msg.contains("field '") {
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
fn mutated_camera_pools_are_rejected_by_name_never_a_panic() {
    let shm = Path::new("/dev/shm");
    let tmp = Arc::new(if shm.is_dir() {
        tempfile::tempdir_in(shm).unwrap()
    } else {
        tempfile::tempdir().unwrap()
    });
    let docs: Vec<serde_json::Value> = [ArmSetup::SingleArm, ArmSetup::Bimanual]
        .into_iter()
        .map(|s| {
            let rows: Vec<_> = builtin_pool(s)
                .poses
                .iter()
                .map(|p| serde_json::json!([p.azimuth, p.elevation, p.distance, 45.0]))
                .collect();
            serde_json::json!({ "rows": rows })
        })
        .collect();
    for d in &docs {
        check(tmp.path(), d.to_string().as_bytes()).unwrap();
    }
    let strategy = (
        0..docs.len(),
        json_edits(3),
        prop::option::weighted(0.3, byte_edits(3)),
    );
    let took = run_cases("camera pool", 2000, strategy, move |(b, edits, bytes)| {
        let text = apply_json(&docs[b], &edits).to_string();
        let data = match &bytes {
            Some(e) => apply_bytes(text.as_bytes(), e),
            None => text.into_bytes(),
        };
        check(tmp.path(), &data)
    });
    assert!(took.as_secs() < 120, "{took:?}");
    assert!(
        ACCEPTED.load(Ordering::Relaxed) > 50,
        "some mutated pools load"
    );
    assert!(REJECTED.load(Ordering::Relaxed) > 50, "some are rejected");
}
