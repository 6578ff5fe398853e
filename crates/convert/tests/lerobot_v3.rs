//! LeRobot v3.0 output read back by lerobot 0.6.1 itself (offline, `root=`), with both
//! video backends: every frame indexed, values equal to the source (as float32), task
//! text right, video frames decoded at the right time within tolerance.

mod common;

use std::path::PathBuf;

use common::{Fixture, check_items, fixture, fixture_with, load, selection};
use dexjoco_convert::{ConvertError, ConvertOptions, Summary, VideoCodec, VideoOptions, convert};
use dexjoco_core::NoProgress;
use serde_json::Value;

fn options(video: VideoOptions) -> ConvertOptions {
    ConvertOptions {
        selection: selection(),
        video,
        batch: 2, // several batches over three episodes
        ..ConvertOptions::default()
    }
}

/// `fx` converted with `video` into `dataset/` of a new temporary folder: the folder, the
/// dataset and convert's summary.
fn converted(fx: &Fixture, video: VideoOptions) -> (tempfile::TempDir, PathBuf, Summary) {
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("dataset");
    let summary = convert(
        fx.inputs.iter().cloned().map(Ok),
        &out,
        &options(video),
        &NoProgress,
    )
    .unwrap();
    (out_dir, out, summary)
}

#[test]
fn stream_copied_h264_loads_in_lerobot_with_pyav_and_torchcodec() {
    let fx = fixture();
    let (out_dir, out, summary) = converted(&fx, VideoOptions::default());
    assert_eq!(
        (summary.episodes, summary.frames, summary.skipped_frames),
        (3, 32, 4)
    );
    assert_eq!((summary.videos_copied, summary.videos_encoded), (6, 0));
    // One file per camera, the static leading frames cut out at augment's keyframes
    // (the file holds the episodes' 32 frames); timestamps continuous at k / 30.
    let front = out.join("videos/observation.images.front/chunk-000/file-000.mp4");
    let times = dexjoco_video::frame_times(&front).unwrap();
    assert_eq!(times.len(), 32);
    for (k, t) in times.iter().enumerate() {
        assert!((t - k as f64 / 30.0).abs() < 1e-4, "frame {k} at {t}");
    }
    let info: Value =
        serde_json::from_str(&fs_err::read_to_string(out.join("meta/info.json")).unwrap()).unwrap();
    assert_eq!(info["codebase_version"], "v3.0");
    assert_eq!(info["total_frames"], 32);
    assert_eq!(info["total_tasks"], 2);
    assert_eq!(
        info["features"]["observation.images.front"]["info"]["video.codec"],
        "h264"
    );
    assert_eq!(info["features"]["action"]["shape"][0], 22);
    for backend in ["pyav", "torchcodec"] {
        let loaded = load(&out, backend);
        check_items(&fx, &loaded, 3.0);
        assert!(
            loaded["stats_keys"]
                .as_array()
                .unwrap()
                .iter()
                .any(|k| k == "observation.images.wrist"),
            "{backend}: image stats"
        );
    }
    // No leftovers beside the dataset.
    let names: Vec<String> = fs_err::read_dir(out_dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, vec!["dataset".to_owned()]);
    assert!(!out.join(".work").exists());
}

#[test]
fn recordings_without_a_keyframe_at_the_cut_are_smart_cut() {
    // As the DexJoCo recorder writes them: no keyframe where the static frames end.
    let fx = fixture_with(false);
    let (_out_dir, out, summary) = converted(&fx, VideoOptions::default());
    // Episodes 0 and 1 (static frames) cut by smart cut: the frames up to the next
    // keyframe re-encoded with the source's own x264 settings (read from the stream),
    // the rest stream-copied, so all six parts join the H.264 files though the
    // re-encoding codec is AV1; every file's frames are its episodes' (lerobot-doctor
    // agrees, in `load`).
    assert_eq!((summary.episodes, summary.frames), (3, 32));
    assert_eq!((summary.videos_copied, summary.videos_encoded), (6, 0));
    assert_eq!(summary.videos_smart_cut, 4, "{summary:?}");
    assert!(summary.frames_reencoded > 0, "{summary:?}");
    let mut frames = 0;
    for f in fs_err::read_dir(out.join("videos/observation.images.front/chunk-000")).unwrap() {
        let info = dexjoco_video::probe(&f.unwrap().path()).unwrap();
        assert_eq!(info.codec, "h264");
        frames += info.frames;
    }
    assert_eq!(frames, 32);
    let loaded = load(&out, "pyav");
    // The re-encoded frames encoded twice (recorded, then cut): a few levels more off.
    check_items(&fx, &loaded, 6.0);
}

#[test]
fn reencoded_av1_loads_in_lerobot() {
    let fx = fixture();
    let video = VideoOptions {
        codec: VideoCodec::Av1,
        reencode: true,
    };
    let (_out_dir, out, summary) = converted(&fx, video);
    assert_eq!((summary.videos_copied, summary.videos_encoded), (0, 6));
    let info =
        dexjoco_video::probe(&out.join("videos/observation.images.wrist/chunk-000/file-000.mp4"))
            .unwrap();
    assert_eq!((info.codec.as_str(), info.frames), ("av1", 32));
    let loaded = load(&out, "pyav");
    check_items(&fx, &loaded, 6.0); // AV1 crf 30 on 64x64: a few levels
}

#[test]
fn refuses_a_non_empty_output_and_bad_input_leaves_nothing() {
    let fx = fixture();
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("dataset");
    fs_err::create_dir_all(&out).unwrap();
    fs_err::write(out.join("keep.txt"), "x").unwrap();
    let opts = options(VideoOptions::default());
    let err = convert(fx.inputs.iter().cloned().map(Ok), &out, &opts, &NoProgress).unwrap_err();
    assert!(err.to_string().contains("not empty"), "{err}");
    assert!(out.join("keep.txt").exists());

    // Overwrite replaces only a dataset convert made.
    let opts = ConvertOptions {
        overwrite: true,
        ..opts
    };
    let err = convert(fx.inputs.iter().cloned().map(Ok), &out, &opts, &NoProgress).unwrap_err();
    assert!(err.to_string().contains("not made by convert"), "{err}");
    fs_err::write(out.join(dexjoco_convert::CONVERT_MARKER), "{}").unwrap();

    // Every episode lacks a camera: the error names the first, nothing is left behind
    // and the old folder is untouched even with overwrite.
    let mut bad = fx.inputs.clone();
    for b in &mut bad {
        b.episode.cameras.retain(|c| c.name != "handcam_rgb");
    }
    let err = convert(bad.into_iter().map(Ok), &out, &opts, &NoProgress)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("none of the 3")
            && err.contains("episode_000000")
            && err.contains("handcam_rgb"),
        "{err}"
    );
    assert!(out.join("keep.txt").exists());
    assert_eq!(fs_err::read_dir(out_dir.path()).unwrap().count(), 1);

    // One episode lacks it and one input cannot be read: those two are left out and
    // named, the rest is written.
    let mut bad = fx.inputs.clone();
    bad[2].episode.cameras.retain(|c| c.name != "handcam_rgb");
    let unreadable = out_dir.path().join("broken_episode");
    let inputs = bad
        .into_iter()
        .map(Ok)
        .chain(std::iter::once(Err(ConvertError::Input {
            path: unreadable.clone(),
            message: "replay.zarr is missing".into(),
        })));
    let s = convert(inputs, &out, &opts, &NoProgress).unwrap();
    assert_eq!(s.episodes, 2);
    let failed: Vec<_> = s.failed.iter().map(|f| f.episode.clone()).collect();
    assert_eq!(
        failed,
        [
            "episode_000002".to_owned(),
            unreadable.display().to_string()
        ]
    );
    assert!(s.failed[0].reason.contains("handcam_rgb"), "{:?}", s.failed);
    assert!(s.failed[1].reason.contains("replay.zarr is missing"));
    let info: serde_json::Value =
        serde_json::from_slice(&fs_err::read(out.join("meta/info.json")).unwrap()).unwrap();
    assert_eq!(info["total_episodes"], 2);

    // The first episode is the broken one: the layout is still the others', and the
    // output does not depend on the batch size.
    let mut bad = fx.inputs.clone();
    bad[0].episode.cameras.retain(|c| c.name != "handcam_rgb");
    let mut trees = Vec::new();
    for batch in [1, 5] {
        let dir = out_dir.path().join(format!("first_broken_{batch}"));
        let opts = ConvertOptions {
            batch,
            ..opts.clone()
        };
        let s = convert(bad.iter().cloned().map(Ok), &dir, &opts, &NoProgress).unwrap();
        assert_eq!(s.episodes, 2);
        let failed: Vec<_> = s.failed.iter().map(|f| f.episode.as_str()).collect();
        assert_eq!(failed, ["episode_000000"]);
        assert!(s.failed[0].reason.contains("handcam_rgb"), "{:?}", s.failed);
        trees.push(dexjoco_testkit::file_tree(&dir));
        fs_err::remove_dir_all(&dir).unwrap();
    }
    assert_eq!(trees[0], trees[1]);

    // Overwrite, with a bad-episodes list.
    let mut opts = opts;
    opts.selection.bad_episodes.insert("episode_000001".into());
    let s = convert(fx.inputs.iter().cloned().map(Ok), &out, &opts, &NoProgress).unwrap();
    assert_eq!(
        (s.episodes, s.excluded.clone()),
        (2, vec!["episode_000001".to_owned()])
    );
    assert!(!out.join("keep.txt").exists());
    assert!(out.join("meta/info.json").exists());
}

#[test]
fn size_caps_split_data_and_video_files_and_lerobot_follows() {
    let fx = fixture();
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("dataset");
    let mut opts = options(VideoOptions::default());
    // Caps below one episode: every episode opens new files.
    opts.v3.data_file_mb = 1e-9;
    opts.v3.video_file_mb = 1e-9;
    convert(fx.inputs.iter().cloned().map(Ok), &out, &opts, &NoProgress).unwrap();
    for f in 0..3 {
        assert!(
            out.join(format!("data/chunk-000/file-{f:03}.parquet"))
                .is_file(),
            "data file {f}"
        );
        assert!(
            out.join(format!(
                "videos/observation.images.wrist/chunk-000/file-{f:03}.mp4"
            ))
            .is_file(),
            "video file {f}"
        );
    }
    let loaded = load(&out, "pyav");
    check_items(&fx, &loaded, 3.0);
}
