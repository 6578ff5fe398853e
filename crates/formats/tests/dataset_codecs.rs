//! A round trip per dataset writer: tiny synthetic episodes written through
//! [`DatasetWriter`] into a temporary folder, read back with the parquet reader or zarrs,
//! and compared (values, shapes, metadata). The Python readers (lerobot, Diffusion
//! Policy) are exercised by `dexjoco-convert`'s tests.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::Arc;

use arrow_array::{Array as _, FixedSizeListArray, Float32Array, Int64Array, RecordBatch};
use dexjoco_core::FrameArray;
use dexjoco_formats::dataset::stats::{ImageSampler, column_stats};
use dexjoco_formats::dataset::{
    DatasetWriter, PreparedEpisode, REPLAY_BUFFER, V3Options, V3Writer, V21Writer, VideoPart,
    ZarrWriter,
};
use dexjoco_video::{Codec, VideoSpec, VideoWriter};
use parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder;
use serde_json::Value;
use zarrs::array::Array;
use zarrs::filesystem::FilesystemStore;

const FPS: u32 = 10;
const SIZE: u32 = 64;

/// The solid colour of frame `k` of episode `e`.
fn colour(e: usize, k: usize) -> [u8; 3] {
    [(40 + 70 * e) as u8, (10 + 12 * k) as u8, 200]
}

/// A `SIZE` x `SIZE` H.264 video of `n` solid frames.
fn write_video(path: &Path, e: usize, n: usize) -> VideoPart {
    let spec = VideoSpec {
        width: SIZE,
        height: SIZE,
        fps: FPS,
        codec: Codec::DEXJOCO,
    };
    let mut w = VideoWriter::create(path, spec).unwrap();
    for k in 0..n {
        w.write_frame(&colour(e, k).repeat((SIZE * SIZE) as usize))
            .unwrap();
    }
    w.finish().unwrap();
    VideoPart {
        name: "front".into(),
        path: path.to_path_buf(),
        temporary: false,
        skip: 0,
        frames: n,
        bytes: fs_err::metadata(path).unwrap().len(),
        info: dexjoco_video::probe(path).unwrap(),
        copied: true,
        reencoded_frames: 0,
        source: path.to_path_buf(),
    }
}

/// Episode `e` of `n` frames: action 3 wide (`e + 0.1 k + 0.01 j`), state 2 wide, and a
/// `front` camera when `video` is given.
fn episode(e: usize, n: usize, instruction: &str, video: Option<VideoPart>) -> PreparedEpisode {
    let rows = |w: usize, scale: f64| -> FrameArray {
        let data = (0..n * w)
            .map(|i| scale * (e as f64 + 0.1 * (i / w) as f64 + 0.01 * (i % w) as f64))
            .collect();
        FrameArray::new(w, data).unwrap()
    };
    let action = rows(3, 1.0);
    let state = rows(2, -1.0);
    let mut stats = BTreeMap::new();
    stats.insert("action".into(), column_stats(action.as_slice(), 3));
    stats.insert(
        "observation.state".into(),
        column_stats(state.as_slice(), 2),
    );
    if video.is_some() {
        let mut sampler = ImageSampler::default();
        for k in 0..n {
            sampler.add_frame(&colour(e, k).repeat((SIZE * SIZE) as usize), SIZE, SIZE);
        }
        stats.insert("observation.images.front".into(), sampler.finish().unwrap());
    }
    PreparedEpisode {
        id: format!("episode_{e:06}"),
        task: "click_mouse".into(),
        instruction: instruction.into(),
        fps: FPS,
        action,
        state,
        action_names: (0..3).map(|j| format!("a{j}")).collect(),
        state_names: (0..2).map(|j| format!("s{j}")).collect(),
        skipped: 0,
        videos: video.into_iter().collect(),
        stats,
        label: None,
        vectors: Vec::new(),
        depth: Vec::new(),
        subtasks: Vec::new(),
        task_aug: vec![instruction.into()],
    }
}

/// Writes `episodes` through `writer` and finishes it.
fn write_all(mut writer: Box<dyn DatasetWriter>, episodes: Vec<PreparedEpisode>) {
    let (count, frames) = (episodes.len(), episodes.iter().map(|e| e.len()).sum());
    for ep in episodes {
        writer.check_compatible(&ep).unwrap();
        writer.write_episode(ep).unwrap();
    }
    assert_eq!((writer.episodes(), writer.frames()), (count, frames));
    writer.finish().unwrap();
}

/// A parquet file: its row groups, schema metadata and rows (one batch).
struct Parquet {
    row_groups: usize,
    metadata: BTreeMap<String, String>,
    rows: RecordBatch,
}

fn read_parquet(path: &Path) -> Parquet {
    let file = std::fs::File::open(path).unwrap();
    let builder = ParquetRecordBatchReaderBuilder::try_new(file).unwrap();
    // The schema metadata, as pyarrow restores it from the embedded arrow schema.
    let metadata = builder
        .schema()
        .metadata()
        .iter()
        .map(|(k, v)| (k.clone(), v.clone()))
        .collect();
    let row_groups = builder.metadata().num_row_groups();
    let mut batches = builder.build().unwrap().map(Result::unwrap);
    let rows = batches.next().unwrap();
    assert!(batches.next().is_none(), "a small file reads as one batch");
    Parquet {
        row_groups,
        metadata,
        rows,
    }
}

fn i64s(batch: &RecordBatch, name: &str) -> Vec<i64> {
    let col = batch.column_by_name(name).unwrap();
    let a = col.as_any().downcast_ref::<Int64Array>().unwrap();
    a.values().to_vec()
}

/// A `fixed_size_list<float32>` column, flattened.
fn f32_vectors(batch: &RecordBatch, name: &str) -> (usize, Vec<f32>) {
    let col = batch.column_by_name(name).unwrap();
    let list = col.as_any().downcast_ref::<FixedSizeListArray>().unwrap();
    let values = list.values().as_any().downcast_ref::<Float32Array>();
    (
        list.value_length() as usize,
        values.unwrap().values().to_vec(),
    )
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&fs_err::read_to_string(path).unwrap()).unwrap()
}

fn keys(v: &Value) -> Vec<&str> {
    v.as_object().unwrap().keys().map(String::as_str).collect()
}

/// The episodes' actions as lerobot stores them.
fn f32_rows(episodes: &[&PreparedEpisode]) -> Vec<f32> {
    episodes
        .iter()
        .flat_map(|e| e.action.as_slice().iter().map(|v| *v as f32))
        .collect()
}

#[test]
fn lerobot_v3_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("v3");
    let eps = [
        episode(0, 5, "click it", None),
        episode(1, 4, "water it", None),
    ];
    let writer = V3Writer::try_new(&root, &eps[0], V3Options::default()).unwrap();
    write_all(Box::new(writer), eps.to_vec());

    let data = read_parquet(&root.join("data/chunk-000/file-000.parquet"));
    assert_eq!(data.row_groups, 2, "one row group per episode");
    let data = data.rows;
    let (width, action) = f32_vectors(&data, "action");
    assert_eq!(width, 3);
    assert_eq!(action, f32_rows(&[&eps[0], &eps[1]]));
    assert_eq!(i64s(&data, "index"), (0..9).collect::<Vec<_>>());
    assert_eq!(i64s(&data, "frame_index")[4..7], [4, 0, 1]);
    assert_eq!(i64s(&data, "task_index")[4..6], [0, 1]);
    let schema = data.schema();
    let columns: Vec<&str> = schema.fields().iter().map(|f| f.name().as_str()).collect();
    assert_eq!(
        columns,
        [
            "action",
            "observation.state",
            "timestamp",
            "frame_index",
            "episode_index",
            "index",
            "task_index"
        ]
    );

    let tasks = read_parquet(&root.join("meta/tasks.parquet"));
    assert_eq!(i64s(&tasks.rows, "task_index"), vec![0, 1]);
    assert!(tasks.metadata.contains_key("pandas"));
    let episodes = read_parquet(&root.join("meta/episodes/chunk-000/file-000.parquet")).rows;
    assert_eq!(i64s(&episodes, "dataset_from_index"), vec![0, 5]);
    assert_eq!(i64s(&episodes, "dataset_to_index"), vec![5, 9]);
    assert_eq!(i64s(&episodes, "length"), vec![5, 4]);

    let info = json(&root.join("meta/info.json"));
    assert_eq!(
        keys(&info),
        [
            "codebase_version",
            "fps",
            "features",
            "total_episodes",
            "total_frames",
            "total_tasks",
            "chunks_size",
            "data_files_size_in_mb",
            "video_files_size_in_mb",
            "data_path",
            "video_path",
            "robot_type",
            "splits"
        ]
    );
    assert_eq!(info["codebase_version"], "v3.0");
    assert_eq!(
        (
            info["total_episodes"].as_u64(),
            info["total_frames"].as_u64()
        ),
        (Some(2), Some(9))
    );
    assert_eq!(info["features"]["action"]["names"][2], "a2");
    assert_eq!(info["features"]["observation.state"]["shape"][0], 2);
    assert_eq!(info["features"]["index"]["dtype"], "int64");
    assert!(info["video_path"].is_null());
    assert_eq!(info["splits"]["train"], "0:2");
    let stats = json(&root.join("meta/stats.json"));
    assert_eq!(stats["index"]["max"][0], 8.0);
    assert_eq!(stats["action"]["count"][0], 9);
}

#[test]
fn lerobot_v3_joins_camera_videos() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("v3");
    let eps: Vec<PreparedEpisode> = (0..2)
        .map(|e| {
            let video = write_video(&dir.path().join(format!("{e}.mp4")), e, 3 + e);
            episode(e, 3 + e, "click it", Some(video))
        })
        .collect();
    let writer = V3Writer::try_new(&root, &eps[0], V3Options::default()).unwrap();
    write_all(Box::new(writer), eps);

    let joined = root.join("videos/observation.images.front/chunk-000/file-000.mp4");
    assert_eq!(dexjoco_video::probe(&joined).unwrap().frames, 7);
    let episodes = read_parquet(&root.join("meta/episodes/chunk-000/file-000.parquet")).rows;
    let from = episodes
        .column_by_name("videos/observation.images.front/from_timestamp")
        .unwrap();
    let from = from.as_any().downcast_ref::<arrow_array::Float64Array>();
    assert_eq!(from.unwrap().values().to_vec(), vec![0.0, 0.3]);
    let info = json(&root.join("meta/info.json"));
    let front = &info["features"]["observation.images.front"];
    assert_eq!(front["dtype"], "video");
    assert_eq!(front["shape"], serde_json::json!([SIZE, SIZE, 3]));
    assert_eq!(front["info"]["video.codec"], "h264");
    assert!(front["info"]["video.g"].is_null(), "stream-copied: no GOP");
    assert_eq!(
        info["video_path"],
        "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
    );
}

#[test]
fn lerobot_v21_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("v21");
    let eps = [
        episode(0, 5, "click it", None),
        episode(1, 4, "click it", None),
    ];
    let writer = V21Writer::try_new(&root, &eps[0], Some("panda".into())).unwrap();
    write_all(Box::new(writer), eps.to_vec());

    let data = read_parquet(&root.join("data/chunk-000/episode_000001.parquet"));
    let (_, action) = f32_vectors(&data.rows, "action");
    assert_eq!(action, f32_rows(&[&eps[1]]));
    assert_eq!(i64s(&data.rows, "index"), vec![5, 6, 7, 8]);
    assert_eq!(i64s(&data.rows, "episode_index"), vec![1; 4]);
    let hf: Value = serde_json::from_str(&data.metadata["huggingface"]).unwrap();
    assert_eq!(hf["info"]["features"]["action"]["length"], 3);

    let lines = |name: &str| -> Vec<Value> {
        fs_err::read_to_string(root.join("meta").join(name))
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect()
    };
    assert_eq!(lines("tasks.jsonl").len(), 1, "one instruction");
    let episodes = lines("episodes.jsonl");
    assert_eq!(episodes[1]["length"], 4);
    assert_eq!(
        lines("episodes_stats.jsonl")[1]["stats"]["index"]["min"][0],
        5.0
    );

    let info = json(&root.join("meta/info.json"));
    assert_eq!(
        keys(&info)[..6],
        [
            "codebase_version",
            "robot_type",
            "total_episodes",
            "total_frames",
            "total_tasks",
            "total_videos"
        ]
    );
    assert_eq!(*keys(&info).last().unwrap(), "features");
    assert_eq!(info["codebase_version"], "v2.1");
    assert_eq!(info["robot_type"], "panda");
    assert_eq!(info["total_chunks"], 1);
    assert_eq!(
        keys(&info["features"]),
        [
            "action",
            "observation.state",
            "timestamp",
            "frame_index",
            "episode_index",
            "index",
            "task_index"
        ]
    );
}

fn zarr_f64(store: &Arc<FilesystemStore>, path: &str) -> (Vec<u64>, Vec<f64>) {
    let a = Array::open(store.clone(), path).unwrap();
    let values = a
        .retrieve_array_subset::<Vec<f64>>(&a.subset_all())
        .unwrap();
    (a.shape().to_vec(), values)
}

#[test]
fn diffusion_policy_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("dp");
    let eps: Vec<PreparedEpisode> = (0..2)
        .map(|e| {
            let video = write_video(&dir.path().join(format!("{e}.mp4")), e, 4 + e);
            episode(e, 4 + e, "click it", Some(video))
        })
        .collect();
    let writer = ZarrWriter::try_new(&root, &eps[0], true).unwrap();
    write_all(Box::new(writer), eps.clone());

    let store = Arc::new(FilesystemStore::new(root.join(REPLAY_BUFFER)).unwrap());
    let (shape, action) = zarr_f64(&store, "/data/action");
    assert_eq!(shape, vec![9, 3]);
    let want: Vec<f64> = eps
        .iter()
        .flat_map(|e| e.action.as_slice().to_vec())
        .collect();
    assert_eq!(action, want, "float64, unrounded");
    let (shape, ts) = zarr_f64(&store, "/data/timestamp");
    assert_eq!(shape, vec![9]);
    assert_eq!(ts[4..6], [0.0, 0.1], "from each episode's first frame");
    let ends = Array::open(store.clone(), "/meta/episode_ends").unwrap();
    let ends = ends.retrieve_array_subset::<Vec<i64>>(&ends.subset_all());
    assert_eq!(ends.unwrap(), vec![4, 9]);

    let images = Array::open(store.clone(), "/data/front").unwrap();
    assert_eq!(images.shape(), [9, u64::from(SIZE), u64::from(SIZE), 3]);
    let pixels = images
        .retrieve_array_subset::<Vec<u8>>(&images.subset_all())
        .unwrap();
    let frame = (SIZE * SIZE * 3) as usize;
    // Frame 1 of episode 1 (H.264 is lossy: within a few levels).
    let got = &pixels[5 * frame..5 * frame + 3];
    for (g, w) in got.iter().zip(colour(1, 1)) {
        assert!(g.abs_diff(w) <= 3, "{got:?} vs {:?}", colour(1, 1));
    }

    assert!(root.join("videos/1/0.mp4").is_file());
    let names = json(&root.join("videos/name_map.json"));
    assert_eq!(names["cameras"], serde_json::json!(["front"]));
    assert_eq!(names["episodes"][1], "episode_000001");
    let zarray = json(&root.join(REPLAY_BUFFER).join("data/action/.zarray"));
    assert_eq!(zarray["compressor"]["cname"], "lz4");
}

#[test]
fn an_episode_of_another_layout_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let first = episode(0, 3, "click it", None);
    let mut other = episode(1, 3, "click it", None);
    other.state = FrameArray::new(1, vec![0.0; 3]).unwrap();
    let writers: Vec<Box<dyn DatasetWriter>> = vec![
        Box::new(V3Writer::try_new(dir.path().join("a"), &first, V3Options::default()).unwrap()),
        Box::new(V21Writer::try_new(dir.path().join("b"), &first, None).unwrap()),
        Box::new(ZarrWriter::try_new(dir.path().join("c"), &first, false).unwrap()),
    ];
    for w in writers {
        let e = w.check_compatible(&other).unwrap_err().to_string();
        assert!(
            e.contains("episode_000001") && e.contains("widths 3/1 differ"),
            "{e}"
        );
    }
}
