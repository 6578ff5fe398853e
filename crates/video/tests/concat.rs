//! Real ffmpeg: join clips by stream copy onto a continuous frame grid; stream frames.

use dexjoco_video::{
    Codec, ConcatInput, Keyframes, VideoReader, VideoSpec, VideoWriter, concat_copy, frame_times,
    keyframe_indices, probe, probe_with_ffmpeg_alone,
};

fn clip(path: &std::path::Path, codec: Codec, n: usize, shade: u8) {
    clip_with(path, codec, n, shade, Vec::new());
}

fn clip_with(path: &std::path::Path, codec: Codec, n: usize, shade: u8, keyframes_at: Vec<usize>) {
    let spec = VideoSpec {
        width: 64,
        height: 64,
        fps: 30,
        codec,
    };
    let keyframes = Keyframes {
        interval: Some(if keyframes_at.is_empty() { 2 } else { 250 }),
        at: keyframes_at,
    };
    let mut w = VideoWriter::create_with(path, spec, &keyframes).unwrap();
    for k in 0..n {
        w.write_frame(&vec![shade.wrapping_add(10 * k as u8); 64 * 64 * 3])
            .unwrap();
    }
    w.finish().unwrap();
}

/// The mean byte of every frame, decoded by streaming.
fn frame_means(path: &std::path::Path) -> Vec<f64> {
    let mut r = VideoReader::open(path, None).unwrap();
    let mut buf = Vec::new();
    let mut means = Vec::new();
    while r.next_frame(&mut buf).unwrap() {
        means.push(buf.iter().map(|v| f64::from(*v)).sum::<f64>() / buf.len() as f64);
    }
    means
}

#[test]
fn clips_join_on_the_frame_grid_without_reencoding() {
    for codec in [
        Codec::DEXJOCO,
        Codec::Av1 {
            crf: 30,
            preset: 12,
        },
    ] {
        let dir = tempfile::tempdir().unwrap();
        let lens = [10usize, 7, 13];
        let parts: Vec<_> = lens
            .iter()
            .enumerate()
            .map(|(i, n)| {
                let p = dir.path().join(format!("{i}.mp4"));
                clip(&p, codec, *n, 40 * i as u8);
                ConcatInput::whole(p)
            })
            .collect();
        let out = dir.path().join("joined.mp4");
        concat_copy(&parts, &out, 30).unwrap();
        let info = probe(&out).unwrap();
        assert_eq!(info.frames, 30, "{codec:?}");
        let t = frame_times(&out).unwrap();
        assert_eq!(t.len(), 30);
        for (k, t) in t.iter().enumerate() {
            // The concat demuxer alone drifts by container-duration rounding (1 ms per
            // clip); the result must sit on k / 30 exactly (to the 1/15360 s tick).
            assert!(
                (t - k as f64 / 30.0).abs() < 1e-4,
                "{codec:?}: frame {k} at {t}"
            );
        }
        // Streaming decode: frame 10 is the second clip's first frame (shade 40).
        let means = frame_means(&out);
        assert!(
            (means[10] - 40.0).abs() < 4.0,
            "{codec:?}: frame 10 mean {}",
            means[10]
        );
        assert_eq!(means.len(), 30);
        assert!(!dir.path().join(".joined.mp4.concat.txt").exists());
    }
}

#[test]
fn a_clip_cut_at_a_forced_keyframe_joins_without_its_leading_frames() {
    let dir = tempfile::tempdir().unwrap();
    let (first, second) = (dir.path().join("a.mp4"), dir.path().join("b.mp4"));
    clip(&first, Codec::DEXJOCO, 6, 0);
    // 20 frames, a keyframe forced at 7 (and none other but the first: interval 250).
    clip_with(&second, Codec::DEXJOCO, 20, 100, vec![7]);
    assert_eq!(keyframe_indices(&second).unwrap(), [0, 7]);
    let out = dir.path().join("joined.mp4");
    let inputs = [
        ConcatInput {
            path: first.clone(),
            skip: 0,
            take: None,
        },
        ConcatInput {
            path: second.clone(),
            skip: 7,
            take: None,
        },
    ];
    concat_copy(&inputs, &out, 30).unwrap();
    assert_eq!(probe(&out).unwrap().frames, 6 + 13);
    let t = frame_times(&out).unwrap();
    for (k, t) in t.iter().enumerate() {
        assert!((t - k as f64 / 30.0).abs() < 1e-4, "frame {k} at {t}");
    }
    // Frame 6 of the join is frame 7 of the second clip (shade 100 + 70).
    let means = frame_means(&out);
    assert!((means[6] - 170.0).abs() < 4.0, "frame 6 mean {}", means[6]);
    assert_eq!(means.len(), 19);
}

#[test]
fn ffmpeg_alone_probes_as_ffprobe_does() {
    let dir = tempfile::tempdir().unwrap();
    for (i, codec) in [
        Codec::DEXJOCO,
        Codec::Av1 {
            crf: 30,
            preset: 12,
        },
    ]
    .into_iter()
    .enumerate()
    {
        let p = dir.path().join(format!("{i}.mp4"));
        clip(&p, codec, 9, 30);
        let by_ffprobe = probe(&p).unwrap();
        let alone = probe_with_ffmpeg_alone(&p).unwrap();
        assert_eq!(alone, by_ffprobe, "{codec:?}");
    }
}

/// Every frame of `path`, decoded by streaming.
fn frames(path: &std::path::Path) -> Vec<Vec<u8>> {
    let mut r = VideoReader::open(path, None).unwrap();
    let mut buf = Vec::new();
    let mut all = Vec::new();
    while r.next_frame(&mut buf).unwrap() {
        all.push(buf.clone());
    }
    all
}

#[test]
fn episodes_are_cut_out_of_a_joined_file_by_stream_copy_bit_for_bit() {
    // Long groups of pictures (x264 medium: B-frames, decoding order differs from
    // presentation order), one keyframe per clip, as episodes joined in a LeRobot file.
    for codec in [
        Codec::DEXJOCO,
        Codec::Av1 {
            crf: 30,
            preset: 12,
        },
    ] {
        let dir = tempfile::tempdir().unwrap();
        let lens = [10usize, 7, 13];
        let parts: Vec<_> = lens
            .iter()
            .enumerate()
            .map(|(i, n)| {
                let p = dir.path().join(format!("{i}.mp4"));
                clip_with(&p, codec, *n, 40 * i as u8, vec![0]);
                ConcatInput::whole(p)
            })
            .collect();
        let joined = dir.path().join("joined.mp4");
        concat_copy(&parts, &joined, 30).unwrap();
        let all = frames(&joined);
        assert_eq!(all.len(), 30);
        // The second episode, then the first, then the last: out of order, ends cut.
        let cut = |skip, take| ConcatInput {
            path: joined.clone(),
            skip,
            take,
        };
        let out = dir.path().join("picked.mp4");
        concat_copy(
            &[cut(10, Some(7)), cut(0, Some(10)), cut(17, None)],
            &out,
            30,
        )
        .unwrap();
        let picked = frames(&out);
        let expected: Vec<_> = all[10..17]
            .iter()
            .chain(&all[0..10])
            .chain(&all[17..])
            .cloned()
            .collect();
        assert_eq!(picked.len(), expected.len(), "{codec:?}");
        assert!(picked == expected, "{codec:?}: frames differ");
        for (k, t) in frame_times(&out).unwrap().iter().enumerate() {
            assert!(
                (t - k as f64 / 30.0).abs() < 1e-4,
                "{codec:?}: frame {k} at {t}"
            );
        }
        // A cut inside a group of pictures is refused, naming the frame.
        let err = concat_copy(&[cut(0, Some(5))], &out, 30).unwrap_err();
        assert!(err.to_string().contains("frame 5"), "{err}");
    }
}
