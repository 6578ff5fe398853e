//! Hostile LeRobot metadata, made by generation: `meta/info.json` mutated (values replaced,
//! removed, added, repeated; bytes edited) and episode rows of arbitrary values (negative,
//! huge and null indices and lengths, non-finite and reversed video spans, missing
//! columns). Opening never panics or hangs; a dataset that opens has only checked values
//! (every placement in range, every path inside its folder), and every rejection names the
//! file.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use arrow_array::builder::{ListBuilder, StringBuilder};
use arrow_array::{ArrayRef, Float64Array, Int64Array, RecordBatch};
use dexjoco_formats::dataset::lerobot_meta::InfoMeta;
use dexjoco_formats::dataset::lerobot_read::LeRobotDataset;
use dexjoco_formats::dataset::parquet::write_file;
use dexjoco_testkit::hostile::{apply_bytes, apply_json, byte_edits, json_edits, run_cases};
use proptest::prelude::*;
use serde_json::{Value, json};

/// A valid info.json of a dataset with one video feature, as lerobot 0.6 writes it.
fn valid_info() -> Value {
    json!({
        "codebase_version": "v3.0",
        "robot_type": "panda",
        "total_episodes": 2,
        "total_frames": 20,
        "total_tasks": 1,
        "chunks_size": 1000,
        "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 200,
        "fps": 30,
        "splits": {"train": "0:2"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4",
        "features": {
            "action": {"dtype": "float32", "shape": [6], "names": null},
            "observation.state": {"dtype": "float32", "shape": [4], "names": null},
            "observation.images.top": {
                "dtype": "video", "shape": [32, 32, 3],
                "names": ["height", "width", "channels"],
                "info": {"video.codec": "av1", "video.fps": 30}
            },
            "timestamp": {"dtype": "float32", "shape": [1], "names": null},
            "frame_index": {"dtype": "int64", "shape": [1], "names": null},
            "episode_index": {"dtype": "int64", "shape": [1], "names": null},
            "index": {"dtype": "int64", "shape": [1], "names": null},
            "task_index": {"dtype": "int64", "shape": [1], "names": null}
        }
    })
}

static ACCEPTED: AtomicUsize = AtomicUsize::new(0);
static REJECTED: AtomicUsize = AtomicUsize::new(0);

/// A parsed info.json fills every path inside the folder, whatever the indices.
fn paths_stay_inside(meta: &InfoMeta) -> Result<(), String> {
    let mut paths = vec![meta.data_path.fill("", u64::MAX, 0)];
    if let Some(v) = &meta.video_path {
        paths.push(v.fill("observation.images.top", 7, u64::MAX));
    }
    for p in paths {
        let path = Path::new(&p);
        if path.is_absolute()
            || path
                .components()
                .any(|c| !matches!(c, std::path::Component::Normal(_)))
            || p.len() > 4096
        {
            return Err(format!("a template filled to {p:?}"));
        }
    }
    for (k, f) in &meta.features {
        let product = f.shape.iter().try_fold(1u64, |a, d| a.checked_mul(*d));
        if product != Some(f.width as u64) || f.width == 0 {
            return Err(format!(
                "feature {k}: width {} of shape {:?}",
                f.width, f.shape
            ));
        }
    }
    Ok(())
}

#[test]
fn mutated_info_files_are_parsed_or_refused_by_name_never_a_panic() {
    let doc = valid_info();
    let path = Path::new("hostile/meta/info.json");
    let strategy = (json_edits(4), prop::option::weighted(0.2, byte_edits(3)));
    let took = run_cases("info.json", 3000, strategy, move |(edits, bytes)| {
        let text = apply_json(&doc, &edits).to_string();
        let data = match &bytes {
            Some(e) => apply_bytes(text.as_bytes(), e),
            None => text.into_bytes(),
        };
        let Ok(Value::Object(mut info)) = serde_json::from_slice::<Value>(&data) else {
            return Ok(());
        };
        match InfoMeta::parse(&mut info, path) {
            Ok(meta) => {
                ACCEPTED.fetch_add(1, Ordering::Relaxed);
                paths_stay_inside(&meta)?;
                // The completed map parses to the same values (what an edit writes).
                let again = InfoMeta::parse(&mut info.clone(), path).map_err(|e| e.to_string())?;
                (again == meta)
                    .then_some(())
                    .ok_or_else(|| "the completed info.json reads differently".to_owned())
            }
            Err(e) => {
                REJECTED.fetch_add(1, Ordering::Relaxed);
                let msg = e.to_string();
                msg.contains("hostile/meta/info.json")
                    .then_some(())
                    .ok_or_else(|| format!("a rejection without the file: {msg}"))
            }
        }
    });
    assert!(took.as_secs() < 60, "{took:?}");
    assert!(
        ACCEPTED.load(Ordering::Relaxed) > 100,
        "some mutated files parse"
    );
    assert!(REJECTED.load(Ordering::Relaxed) > 100, "some are refused");
}

/// Episode rows: `n` rows of every placement column, some left out.
#[derive(Debug, Clone)]
struct Rows {
    episode: Vec<Option<i64>>,
    length: Vec<Option<i64>>,
    chunk: Vec<Option<i64>>,
    file: Vec<Option<i64>>,
    from_index: Vec<Option<i64>>,
    to_index: Vec<Option<i64>>,
    video_chunk: Vec<Option<i64>>,
    from: Vec<f64>,
    to: Vec<f64>,
    tasks: Vec<Option<String>>,
    missing: Option<usize>,
}

impl Rows {
    /// `lengths.len()` consistent rows: numbered, placed one after the other.
    fn consistent(lengths: &[i64]) -> Self {
        let n = lengths.len();
        let mut at = 0;
        let (mut from_index, mut to_index, mut from, mut to) = (vec![], vec![], vec![], vec![]);
        for l in lengths {
            from_index.push(Some(at));
            to_index.push(Some(at + l));
            from.push(at as f64 / 30.0);
            to.push((at + l) as f64 / 30.0);
            at += l;
        }
        Self {
            episode: (0..n as i64).map(Some).collect(),
            length: lengths.iter().copied().map(Some).collect(),
            chunk: vec![Some(0); n],
            file: vec![Some(0); n],
            from_index,
            to_index,
            video_chunk: vec![Some(0); n],
            from,
            to,
            tasks: vec![Some("t".into()); n],
            missing: None,
        }
    }

    /// Sets column `col` of row `row` (modulo the counts) to the hostile `v`.
    fn edit(&mut self, col: usize, row: usize, v: Option<i64>, f: f64) {
        let row = row % self.episode.len();
        match col % 10 {
            0 => self.episode[row] = v,
            1 => self.length[row] = v,
            2 => self.chunk[row] = v,
            3 => self.file[row] = v,
            4 => self.from_index[row] = v,
            5 => self.to_index[row] = v,
            6 => self.video_chunk[row] = v,
            7 => self.from[row] = f,
            8 => self.to[row] = f,
            _ => self.tasks[row] = None,
        }
    }
}

/// Consistent rows with 0 to 3 hostile values, sometimes a column left out.
fn rows() -> impl Strategy<Value = Rows> {
    let hostile_int = prop_oneof![
        Just(None),
        prop::sample::select(vec![
            -1,
            i64::MIN,
            i64::MAX,
            1 << 40,
            (1 << 40) + 1,
            1 << 62,
            3,
            0
        ])
        .prop_map(Some),
    ];
    let hostile_float =
        prop::sample::select(vec![f64::NAN, f64::INFINITY, -1.0, 1e300, -0.0, 0.5, 1e12]);
    (
        prop::collection::vec(1i64..40, 1..5),
        prop::collection::vec((0usize..10, 0usize..5, hostile_int, hostile_float), 0..4),
        prop::option::weighted(0.1, 0usize..11),
    )
        .prop_map(|(lengths, edits, missing)| {
            let mut r = Rows::consistent(&lengths);
            for (col, row, v, f) in edits {
                r.edit(col, row, v, f);
            }
            r.missing = missing;
            r
        })
}

/// The rows as an episodes file's batch (a column left out where `missing` says).
fn batch(r: &Rows) -> RecordBatch {
    let int = |v: &Vec<Option<i64>>| Arc::new(Int64Array::from(v.clone())) as ArrayRef;
    let float = |v: &Vec<f64>| Arc::new(Float64Array::from(v.clone())) as ArrayRef;
    let mut tasks = ListBuilder::new(StringBuilder::new());
    for t in &r.tasks {
        match t {
            Some(t) => {
                tasks.values().append_value(t);
                tasks.append(true);
            }
            None => tasks.append(false),
        }
    }
    let cols: Vec<(&str, ArrayRef)> = vec![
        ("episode_index", int(&r.episode)),
        ("tasks", Arc::new(tasks.finish())),
        ("length", int(&r.length)),
        ("data/chunk_index", int(&r.chunk)),
        ("data/file_index", int(&r.file)),
        ("dataset_from_index", int(&r.from_index)),
        ("dataset_to_index", int(&r.to_index)),
        (
            "videos/observation.images.top/chunk_index",
            int(&r.video_chunk),
        ),
        ("videos/observation.images.top/file_index", int(&r.file)),
        (
            "videos/observation.images.top/from_timestamp",
            float(&r.from),
        ),
        ("videos/observation.images.top/to_timestamp", float(&r.to)),
    ];
    let cols: Vec<(&str, ArrayRef)> = cols
        .into_iter()
        .enumerate()
        .filter(|(i, _)| Some(*i) != r.missing)
        .map(|(_, c)| c)
        .collect();
    RecordBatch::try_from_iter(cols).unwrap()
}

/// A dataset that opened: every value read later is in range.
fn opened_is_checked(ds: &LeRobotDataset) -> Result<(), String> {
    let e = |e: dexjoco_formats::DatasetError| e.to_string();
    let lengths = ds.lengths().map_err(e)?;
    if lengths.iter().any(|l| !(0..=1 << 40).contains(l)) {
        return Err(format!("lengths {lengths:?} accepted"));
    }
    for p in ds.data_files().map_err(e)? {
        if !p.starts_with(&ds.root) {
            return Err(format!("data file {} outside", p.display()));
        }
    }
    let chunk = ds.int_column("videos/observation.images.top/chunk_index");
    let file = ds.int_column("videos/observation.images.top/file_index");
    if let (Ok(c), Ok(f)) = (chunk, file) {
        for (c, f) in c.into_iter().zip(f) {
            if !ds
                .video_file("observation.images.top", c, f)
                .starts_with(&ds.root)
            {
                return Err("a video file outside".into());
            }
        }
    }
    Ok(())
}

#[test]
fn hostile_episode_rows_are_refused_by_name_never_a_panic() {
    static OPENED: AtomicUsize = AtomicUsize::new(0);
    let tmp = Arc::new(tempfile::tempdir().unwrap());
    let case = Arc::new(AtomicUsize::new(0));
    let took = run_cases("episode rows", 600, rows(), move |r| {
        let root = tmp
            .path()
            .join(format!("ds{}", case.fetch_add(1, Ordering::Relaxed)));
        let meta = root.join("meta");
        fs_err::create_dir_all(meta.join("episodes/chunk-000")).unwrap();
        let mut info = valid_info();
        info["total_episodes"] = json!(r.episode.len());
        fs_err::write(meta.join("info.json"), info.to_string()).unwrap();
        let tasks = RecordBatch::try_from_iter([
            (
                "task_index",
                Arc::new(Int64Array::from(vec![0])) as ArrayRef,
            ),
            (
                "task",
                Arc::new(arrow_array::StringArray::from(vec!["t"])) as ArrayRef,
            ),
        ])
        .unwrap();
        write_file(&meta.join("tasks.parquet"), &tasks).unwrap();
        write_file(
            &meta.join("episodes/chunk-000/file-000.parquet"),
            &batch(&r),
        )
        .unwrap();
        let result = match LeRobotDataset::open(&root) {
            Ok(ds) => {
                OPENED.fetch_add(1, Ordering::Relaxed);
                opened_is_checked(&ds)
            }
            Err(e) => {
                let msg = e.to_string();
                msg.contains(&root.display().to_string())
                    .then_some(())
                    .ok_or_else(|| format!("a rejection without the file: {msg}"))
            }
        };
        fs_err::remove_dir_all(&root).unwrap();
        result
    });
    assert!(took.as_secs() < 120, "{took:?}");
    assert!(OPENED.load(Ordering::Relaxed) > 5, "some datasets open");
}
