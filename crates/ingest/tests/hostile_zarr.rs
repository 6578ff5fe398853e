//! Hostile DexJoCo raw episodes, made by mutating valid `replay.zarr` stores: `.zarray`
//! and `.zgroup` JSON (shapes, chunks, dtypes, compressors, orders...), chunk bytes,
//! missing files, one array's metadata over another's. Read and validated as ingest
//! does: no panic, no hang, and every rejection names the file and the field.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use dexjoco_core::{TaskSet, TaskSpec, synth};
use dexjoco_formats::{Source, SourceKind, raw};
use dexjoco_ingest::{ValidationOptions, validate};
use dexjoco_testkit::hostile::{
    ByteEdit, JsonEdit, apply_bytes, apply_json, byte_edits, json_edits, run_cases,
};
use proptest::prelude::*;
use proptest::sample::Index;

/// A store's files: path relative to the episode folder, bytes.
type Files = Vec<(String, Vec<u8>)>;

fn read_files(root: &Path, dir: &Path, out: &mut Files) {
    let mut entries: Vec<_> = fs_err::read_dir(dir).unwrap().flatten().collect();
    entries.sort_by_key(fs_err::DirEntry::file_name);
    for e in entries {
        let p = e.path();
        if p.is_dir() {
            read_files(root, &p, out);
        } else {
            let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
            out.push((rel, fs_err::read(&p).unwrap()));
        }
    }
}

/// Valid episodes: (task, files).
fn bases() -> Vec<(String, Files)> {
    let tmp = tempfile::tempdir().unwrap();
    [("click_mouse", 10), ("bimanual_unlock_ipad", 6)]
        .into_iter()
        .enumerate()
        .map(|(i, (task, frames))| {
            let spec = TaskSpec::builtin(task).unwrap();
            let dir = tmp.path().join(format!("{i}"));
            raw::write_replay_zarr(&dir, &synth::episode(spec, frames, i as u64)).unwrap();
            let mut files = Vec::new();
            read_files(&dir, &dir, &mut files);
            (task.to_owned(), files)
        })
        .collect()
}

/// One change to a store.
#[derive(Debug, Clone)]
enum ZarrEdit {
    ArrayMeta(Index, Vec<JsonEdit>),
    GroupMeta(Index, Vec<JsonEdit>),
    Chunk(Index, Vec<ByteEdit>),
    Remove(Index),
    MetaOverAnother(Index, Index),
    Shape(Index, Vec<u64>),
}

fn zarr_edit() -> impl Strategy<Value = ZarrEdit> {
    prop_oneof![
        6 => (any::<Index>(), json_edits(3)).prop_map(|(i, e)| ZarrEdit::ArrayMeta(i, e)),
        1 => (any::<Index>(), json_edits(2)).prop_map(|(i, e)| ZarrEdit::GroupMeta(i, e)),
        4 => (any::<Index>(), byte_edits(4)).prop_map(|(i, e)| ZarrEdit::Chunk(i, e)),
        1 => any::<Index>().prop_map(ZarrEdit::Remove),
        1 => (any::<Index>(), any::<Index>()).prop_map(|(a, b)| ZarrEdit::MetaOverAnother(a, b)),
        3 => (any::<Index>(), prop::collection::vec(
                prop::sample::select(vec![0u64, 1, 2, 5, 9, 10, 11, 23, 31, 46, 1024, 1 << 31, u64::MAX]),
                0..4))
            .prop_map(|(i, s)| ZarrEdit::Shape(i, s)),
    ]
}

fn pick<'a>(
    files: &'a mut Files,
    i: &Index,
    pred: impl Fn(&str) -> bool,
) -> Option<&'a mut Vec<u8>> {
    let idx: Vec<usize> = (0..files.len()).filter(|&k| pred(&files[k].0)).collect();
    if idx.is_empty() {
        return None;
    }
    Some(&mut files[idx[i.index(idx.len())]].1)
}

fn edit_json(bytes: &mut Vec<u8>, f: impl FnOnce(serde_json::Value) -> serde_json::Value) {
    if let Ok(v) = serde_json::from_slice(bytes) {
        *bytes = serde_json::to_vec(&f(v)).unwrap();
    }
}

fn apply(mut files: Files, edits: &[ZarrEdit]) -> Files {
    let is_meta = |p: &str| p.ends_with(".zarray");
    let is_chunk = |p: &str| !p.rsplit('/').next().unwrap_or("").starts_with('.');
    for e in edits {
        match e {
            ZarrEdit::ArrayMeta(i, j) => {
                if let Some(b) = pick(&mut files, i, is_meta) {
                    edit_json(b, |v| apply_json(&v, j));
                }
            }
            ZarrEdit::GroupMeta(i, j) => {
                if let Some(b) = pick(&mut files, i, |p| p.ends_with(".zgroup")) {
                    edit_json(b, |v| apply_json(&v, j));
                }
            }
            ZarrEdit::Chunk(i, c) => {
                if let Some(b) = pick(&mut files, i, is_chunk) {
                    *b = apply_bytes(b, c);
                }
            }
            ZarrEdit::Remove(i) => {
                let k = i.index(files.len());
                files.remove(k);
            }
            ZarrEdit::MetaOverAnother(a, b) => {
                let from = pick(&mut files, a, is_meta).cloned();
                if let (Some(from), Some(to)) = (from, pick(&mut files, b, is_meta)) {
                    *to = from;
                }
            }
            ZarrEdit::Shape(i, s) => {
                if let Some(b) = pick(&mut files, i, is_meta) {
                    edit_json(b, |mut v| {
                        if let Some(m) = v.as_object_mut() {
                            m.insert("shape".into(), serde_json::json!(s));
                        }
                        v
                    });
                }
            }
        }
    }
    files
}

/// Cases read whole (then validated) and rejected by the reader.
static READ: AtomicUsize = AtomicUsize::new(0);
static REJECTED: AtomicUsize = AtomicUsize::new(0);

/// Writes the files as `<root>/<task>/episode_NNNNNN/`, reads and validates them as
/// ingest does; a rejection must name the episode folder and the field.
fn check(root: &Path, n: usize, task: &str, files: &Files) -> Result<(), String> {
    let dir: PathBuf = root.join(task).join(format!("episode_{n:06}"));
    for (rel, bytes) in files {
        let p = dir.join(rel);
        fs_err::create_dir_all(p.parent().unwrap()).unwrap();
        fs_err::write(&p, bytes).unwrap();
    }
    fs_err::create_dir_all(&dir).unwrap();
    let tasks = TaskSet::builtin();
    let source = Source {
        path: dir.clone(),
        kind: SourceKind::Raw,
    };
    let result = match source.read(tasks) {
        Err(e) => {
            REJECTED.fetch_add(1, Ordering::Relaxed);
            let msg = e.to_string();
            if msg.contains(&format!("file '{}'", dir.display())) && msg.contains("field '") {
                Ok(())
            } else {
                Err(format!("a rejection without file and field: {msg}"))
            }
        }
        Ok(r) => {
            READ.fetch_add(1, Ordering::Relaxed);
            let spec = tasks.get(&r.episode.task).expect("the path's task");
            validate(&r.episode, spec, &dir, &ValidationOptions::default())
                .into_iter()
                .find(|p| p.file.as_deref() != Some(dir.as_path()) || p.field.is_none())
                .map_or(Ok(()), |p| {
                    Err(format!("a problem without file and field: {p:?}"))
                })
        }
    };
    fs_err::remove_dir_all(&dir).unwrap();
    result
}

#[test]
fn mutated_zarr_stores_are_rejected_by_name_never_a_panic() {
    let bases = Arc::new(bases());
    // Thousands of small stores: in memory where the machine has a RAM disk.
    let shm = Path::new("/dev/shm");
    let tmp = Arc::new(if shm.is_dir() {
        tempfile::tempdir_in(shm).unwrap()
    } else {
        tempfile::tempdir().unwrap()
    });
    // The valid stores read back.
    for (k, (task, files)) in bases.iter().enumerate() {
        check(tmp.path(), 900_000 + k, task, files).unwrap();
    }
    let counter = Arc::new(AtomicUsize::new(0));
    let strategy = (0..bases.len(), prop::collection::vec(zarr_edit(), 1..4));
    let took = run_cases("zarr stores", 1500, strategy, move |(b, edits)| {
        let (task, files) = &bases[b];
        let n = counter.fetch_add(1, Ordering::Relaxed);
        check(tmp.path(), n, task, &apply(files.clone(), &edits))
    });
    assert!(took.as_secs() < 180, "{took:?}");
    assert!(
        READ.load(Ordering::Relaxed) > 100,
        "some mutated stores read whole"
    );
    assert!(REJECTED.load(Ordering::Relaxed) > 100, "some are rejected");
}
