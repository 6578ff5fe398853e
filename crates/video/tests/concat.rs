//! Real ffmpeg: join clips by stream copy onto a continuous frame grid; stream frames.

use dexjoco_video::{Codec, VideoReader, VideoSpec, VideoWriter, concat_copy, frame_times, probe};

fn clip(path: &std::path::Path, codec: Codec, n: usize, shade: u8) {
    let spec = VideoSpec {
        width: 64,
        height: 64,
        fps: 30,
        codec,
    };
    let mut w = VideoWriter::create_with(path, spec, Some(2)).unwrap();
    for k in 0..n {
        w.write_frame(&vec![shade.wrapping_add(10 * k as u8); 64 * 64 * 3])
            .unwrap();
    }
    w.finish().unwrap();
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
                p
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
        let mut r = VideoReader::open(&out, None).unwrap();
        let mut buf = Vec::new();
        let mut k = 0;
        while r.next_frame(&mut buf).unwrap() {
            if k == 10 {
                let mean = buf.iter().map(|v| f64::from(*v)).sum::<f64>() / buf.len() as f64;
                assert!((mean - 40.0).abs() < 4.0, "{codec:?}: frame 10 mean {mean}");
            }
            k += 1;
        }
        assert_eq!(k, 30);
        assert!(!dir.path().join(".joined.mp4.concat.txt").exists());
    }
}
