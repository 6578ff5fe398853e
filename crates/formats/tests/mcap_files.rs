//! MCAP teleop logs round trip bit for bit, and damaged files are named.

use dexjoco_core::{Episode, TaskSet, TaskSpec, synth};
use dexjoco_formats::EpisodeMeta;
use dexjoco_formats::mcap::{read_episode_mcap, write_episode_mcap};
use dexjoco_formats::{FormatError, ProblemCode};

#[test]
fn mcap_round_trip_is_bit_exact_for_awkward_values() {
    let task = TaskSpec::builtin("bimanual_unlock_ipad").unwrap();
    let mut ep = synth::episode(task, 12, 3);
    // Values whose decimal forms are long or special: all must come back bit-identical.
    let awkward = [
        -0.0,
        f64::MIN_POSITIVE,
        5e-324,
        0.1 + 0.2,
        1.0 / 3.0,
        f64::MAX,
        -1e-300,
        123_456_789.123_456_79,
    ];
    let state = ep.arrays.get_mut(Episode::STATE).unwrap();
    for (i, v) in awkward.iter().enumerate() {
        state.row_mut(i)[20] = *v;
    }
    let action = ep.arrays.get_mut(Episode::ACTION).unwrap();
    action.row_mut(4)[0] = 0.1 + 0.7;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ep.mcap");
    let meta = EpisodeMeta {
        operator: Some("op".into()),
        ..EpisodeMeta::default()
    };
    write_episode_mcap(&path, &ep, task, &meta).unwrap();
    let bytes = fs_err::read(&path).unwrap();
    let back = read_episode_mcap(&path, &bytes, TaskSet::builtin()).unwrap();
    assert_eq!(back.meta.operator.as_deref(), Some("op"));
    assert_eq!(back.episode.id, ep.id);
    for (name, a) in &ep.arrays {
        let b = back.episode.array(name).unwrap();
        assert_eq!(a.width(), b.width(), "{name}");
        for (x, y) in a.as_slice().iter().zip(b.as_slice()) {
            assert_eq!(x.to_bits(), y.to_bits(), "{name}: {x} vs {y}");
        }
    }
}

#[test]
fn truncated_and_foreign_files_are_named() {
    let task = TaskSpec::builtin("click_mouse").unwrap();
    let ep = synth::episode(task, 30, 1);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ep.mcap");
    write_episode_mcap(&path, &ep, task, &EpisodeMeta::default()).unwrap();
    let bytes = fs_err::read(&path).unwrap();
    for cut in [bytes.len() - 1, bytes.len() / 2, 9] {
        match read_episode_mcap(&path, &bytes[..cut], TaskSet::builtin()) {
            Err(FormatError::Input(p)) => {
                assert_eq!(p.code, ProblemCode::Truncated, "cut at {cut}: {p}")
            }
            other => panic!("cut at {cut}: {other:?}"),
        }
    }
    match read_episode_mcap(&path, b"PK\x03\x04 a zip", TaskSet::builtin()) {
        Err(FormatError::Input(p)) => assert_eq!(p.code, ProblemCode::Corrupt),
        other => panic!("{other:?}"),
    }
}
