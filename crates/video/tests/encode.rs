//! Real ffmpeg: encode synthetic frames, probe and decode them back.

use dexjoco_video::{Codec, VideoSpec, VideoWriter, decode_rgb, probe};

const W: u32 = 64;
const H: u32 = 64; // SVT-AV1 needs at least 64 rows

/// A moving colour gradient: frame `k` shifted by `k` pixels.
fn frame(k: usize) -> Vec<u8> {
    let mut f = Vec::with_capacity((W * H * 3) as usize);
    for y in 0..H as usize {
        for x in 0..W as usize {
            f.extend_from_slice(&[((x + 2 * k) * 4 % 256) as u8, (y * 5 % 256) as u8, 128]);
        }
    }
    f
}

fn encode(path: &std::path::Path, codec: Codec, n: usize) -> usize {
    let mut w = VideoWriter::create(
        path,
        VideoSpec {
            width: W,
            height: H,
            fps: 30,
            codec,
        },
    )
    .unwrap();
    for k in 0..n {
        w.write_frame(&frame(k)).unwrap();
    }
    w.finish().unwrap()
}

#[test]
fn h264_as_the_dexjoco_recorder_writes_it_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("front.mp4");
    assert_eq!(encode(&path, Codec::DEXJOCO, 12), 12);
    let info = probe(&path).unwrap();
    assert_eq!(
        (info.codec.as_str(), info.pix_fmt.as_str()),
        ("h264", "yuv420p")
    );
    assert_eq!(info.profile.as_deref(), Some("High"));
    assert_eq!((info.width, info.height, info.frames), (W, H, 12));
    assert!((info.fps - 30.0).abs() < 1e-9, "{}", info.fps);
    let frames = decode_rgb(&path).unwrap();
    assert_eq!(frames.len(), 12);
    for (k, f) in frames.iter().enumerate() {
        let want = frame(k);
        let mean = f
            .iter()
            .zip(&want)
            .map(|(a, b)| (*a as f64 - *b as f64).abs())
            .sum::<f64>()
            / f.len() as f64;
        assert!(mean < 4.0, "frame {k}: mean abs difference {mean}");
    }
    // No temporary file is left behind.
    let names: Vec<_> = fs_err::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("front.mp4")]);
}

#[test]
fn same_frames_give_identical_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.mp4"), dir.path().join("b.mp4"));
    encode(&a, Codec::DEXJOCO, 20);
    encode(&b, Codec::DEXJOCO, 20);
    assert_eq!(fs_err::read(&a).unwrap(), fs_err::read(&b).unwrap());
}

#[test]
fn av1_through_svt() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("front_av1.mp4");
    encode(
        &path,
        Codec::Av1 {
            crf: 30,
            preset: 12,
        },
        8,
    );
    let info = probe(&path).unwrap();
    assert_eq!((info.codec.as_str(), info.frames), ("av1", 8));
    assert_eq!(decode_rgb(&path).unwrap().len(), 8);
}

#[test]
fn wrong_frame_size_names_file_and_frame_and_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.mp4");
    let mut w = VideoWriter::create(
        &path,
        VideoSpec {
            width: W,
            height: H,
            fps: 30,
            codec: Codec::DEXJOCO,
        },
    )
    .unwrap();
    w.write_frame(&frame(0)).unwrap();
    let err = w.write_frame(&[0u8; 10]).unwrap_err().to_string();
    assert!(err.contains("bad.mp4") && err.contains("frame 1"), "{err}");
    drop(w);
    assert_eq!(
        fs_err::read_dir(dir.path()).unwrap().count(),
        0,
        "an unfinished video leaves no file"
    );
}

#[test]
fn a_failing_encoder_reports_ffmpeg_s_message() {
    let dir = tempfile::tempdir().unwrap();
    // Odd sizes cannot be yuv420p with libx264.
    let path = dir.path().join("odd.mp4");
    let mut w = VideoWriter::create(
        &path,
        VideoSpec {
            width: 33,
            height: 33,
            fps: 30,
            codec: Codec::DEXJOCO,
        },
    )
    .unwrap();
    let f = vec![0u8; 33 * 33 * 3];
    let mut result = Ok(());
    for _ in 0..50 {
        result = w.write_frame(&f);
        if result.is_err() {
            break;
        }
    }
    let err = match result {
        Err(e) => e.to_string(),
        Ok(()) => w.finish().unwrap_err().to_string(),
    };
    assert!(err.contains("odd.mp4"), "{err}");
    assert!(!path.exists());
}

#[test]
fn finished_encoders_cpu_time_is_counted() {
    let dir = tempfile::tempdir().unwrap();
    let before = dexjoco_video::finished_children_cpu_seconds().expect("/proc/self/stat");
    for k in 0..3 {
        encode(&dir.path().join(format!("{k}.mp4")), Codec::DEXJOCO, 60);
    }
    let after = dexjoco_video::finished_children_cpu_seconds().unwrap();
    // Three ffmpeg processes started, encoded 60 frames each and were reaped.
    assert!(after - before >= 0.01, "{before} -> {after}");
}
