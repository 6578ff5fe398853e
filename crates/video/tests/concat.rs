//! Real ffmpeg: join clips by stream copy onto a continuous frame grid; stream frames.

use dexjoco_video::{
    Codec, ConcatInput, CutPoints, Encoding, Keyframes, VideoReader, VideoSpec, VideoWriter,
    concat_copy, frame_times, keyframe_indices, probe, probe_with_ffmpeg_alone, smart_cut,
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
        // An end inside a group of pictures: bit-exact where the packets decoded before
        // it are exactly the frames before it, else refused naming the frame.
        let cuts = CutPoints::of(&joined).unwrap();
        for end in 1..10 {
            match concat_copy(&[cut(0, Some(end))], &out, 30) {
                Ok(()) => {
                    assert!(cuts.can_end(end), "{codec:?}: ended at {end}");
                    assert!(frames(&out) == all[..end], "{codec:?}: end {end}");
                }
                Err(e) => {
                    assert!(!cuts.can_end(end), "{codec:?}: {e}");
                    assert!(e.to_string().contains(&format!("before {end} ")), "{e}");
                }
            }
        }
    }
}

/// A moving gradient, `n` frames, with `keyframes`.
fn textured(path: &std::path::Path, codec: Codec, n: usize, keyframes: &Keyframes) {
    let spec = VideoSpec {
        width: 64,
        height: 64,
        fps: 30,
        codec,
    };
    let mut w = VideoWriter::create_with(path, spec, keyframes).unwrap();
    for k in 0..n {
        let frame: Vec<u8> = (0..64 * 64 * 3)
            .map(|i| {
                let (x, y, c) = ((i / 3) % 64, i / 192, i % 3);
                let wave = ((x as f64 + 2.0 * k as f64) / 7.0).sin() * 60.0
                    + (y as f64 / 9.0).cos() * 40.0;
                (128.0 + wave) as u8 / (c as u8 + 1)
            })
            .collect();
        w.write_frame(&frame).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn a_cut_off_a_keyframe_reencodes_only_the_frames_before_the_next_keyframe() {
    let av1 = Codec::Av1 {
        crf: 30,
        preset: 12,
    };
    for (codec, interval) in [(Codec::DEXJOCO, None), (av1, Some(8))] {
        let dir = tempfile::tempdir().unwrap();
        let src = dir.path().join("src.mp4");
        let keyframes = Keyframes {
            interval,
            at: vec![0, 20],
        };
        textured(&src, codec, 40, &keyframes);
        let keys = keyframe_indices(&src).unwrap();
        let cuts = CutPoints::of(&src).unwrap();
        let next = *keys.iter().find(|k| **k > 5).unwrap();
        // Frame 35 is inside a group of pictures: the copy ends at the last frame it can.
        let last = (next..=35).rev().find(|f| cuts.can_end(*f)).unwrap();
        // The first candidate's headers differ from the source's (another preset or
        // codec); the second is how the source was encoded.
        let other = Encoding {
            codec: Codec::H264 {
                crf: 21,
                preset: dexjoco_video::X264Preset::Ultrafast,
            },
            interval,
        };
        let candidates = [other, Encoding { codec, interval }];
        let cut = smart_cut(&src, 5, 30, &cuts, &candidates, dir.path())
            .unwrap()
            .expect("the source's own settings match");
        let reencoded = next - 5 + 35 - last;
        assert_eq!(
            (cut.candidate, cut.reencoded),
            (Some(1), reencoded),
            "{codec:?}"
        );
        assert!(reencoded < 30, "{codec:?}: keyframes {keys:?}");
        let out = dir.path().join("cut.mp4");
        concat_copy(&cut.inputs, &out, 30).unwrap();
        let (all, got) = (frames(&src), frames(&out));
        assert_eq!(got.len(), 30, "{codec:?}");
        assert!(
            got[next - 5..last - 5] == all[next..last],
            "{codec:?}: copied frames differ"
        );
        let head = got[..next - 5].iter().zip(&all[5..next]);
        let tail = got[last - 5..].iter().zip(&all[last..35]);
        for (k, (a, b)) in head.chain(tail).enumerate() {
            let err = a
                .iter()
                .zip(b)
                .map(|(x, y)| f64::from(x.abs_diff(*y)))
                .sum::<f64>()
                / a.len() as f64;
            assert!(
                err < 3.0,
                "{codec:?}: re-encoded frame {k} off by {err:.2} levels"
            );
        }
        // No candidate: none is made.
        assert_eq!(
            smart_cut(&src, 5, 30, &cuts, &[other], dir.path()).unwrap(),
            None
        );
    }
}

#[test]
fn hundreds_of_forced_keyframes_are_all_keyframes() {
    // A re-encoded LeRobot file forces one per episode: more than ffmpeg's expression
    // parser takes as one sum, so they are passed as times.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("many.mp4");
    let at: Vec<usize> = (0..300).map(|k| k * 3 + k % 2).collect();
    let keyframes = Keyframes {
        interval: None,
        at: at.clone(),
    };
    textured(&path, Codec::DEXJOCO, 905, &keyframes);
    let found = keyframe_indices(&path).unwrap();
    let missing: Vec<&usize> = at.iter().filter(|k| !found.contains(k)).collect();
    assert!(missing.is_empty(), "not keyframes: {missing:?}");
}
