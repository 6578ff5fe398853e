//! The raw reader checks every array's length against the others and `episode_ends`
//! against all of them, naming file, field and frame; an episode whose timestamps stop
//! early used to be read and then panicked whoever indexed them by the action's length.

use dexjoco_core::{Episode, TaskSpec, synth};
use dexjoco_formats::{FormatError, ProblemCode, raw};

fn write(dir: &std::path::Path, ep: &Episode) {
    raw::write_replay_zarr(dir, ep).unwrap();
}

#[test]
fn a_short_array_is_rejected_naming_file_field_and_frame() {
    let task = TaskSpec::builtin("click_mouse").unwrap();
    let tmp = tempfile::tempdir().unwrap();
    for (name, len) in [(Episode::TIMESTAMP, 30), (Episode::STATE, 12)] {
        let ep = synth::episode(task, 40, 1);
        let dir = tmp.path().join(format!("click_mouse/episode_{len:06}"));
        write(&dir, &ep);
        // The array's shape says fewer frames (its one chunk still holds 40: an edge
        // chunk is stored whole).
        let zarray = dir.join("replay.zarr/data").join(name).join(".zarray");
        let mut meta: serde_json::Value =
            serde_json::from_slice(&fs_err::read(&zarray).unwrap()).unwrap();
        meta["shape"][0] = len.into();
        fs_err::write(&zarray, meta.to_string()).unwrap();
        let err = raw::read_raw_episode(&dir, task).unwrap_err();
        let FormatError::Input(p) = &err else {
            panic!("{err}")
        };
        assert_eq!(p.code, ProblemCode::WrongLength, "{err}");
        assert_eq!(p.field.as_deref(), Some(name), "{err}");
        assert_eq!(p.frame, Some(len), "{err}");
        assert_eq!(p.file.as_deref(), Some(dir.as_path()), "{err}");
        assert!(err.to_string().contains("'action' has 40"), "{err}");
    }
}

#[test]
fn episode_ends_must_match_every_array() {
    let task = TaskSpec::builtin("click_mouse").unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("click_mouse/episode_000000");
    write(&dir, &synth::episode(task, 40, 2));
    // episode_ends says 25: a chunk of 1 int64, uncompressed.
    fs_err::write(
        dir.join("replay.zarr/meta/episode_ends/0"),
        25i64
            .to_le_bytes()
            .iter()
            .chain(&[0u8; 8 * 1023])
            .copied()
            .collect::<Vec<u8>>(),
    )
    .unwrap();
    let err = raw::read_raw_episode(&dir, task).unwrap_err();
    let FormatError::Input(p) = &err else {
        panic!("{err}")
    };
    assert_eq!(p.code, ProblemCode::EpisodeEndsMismatch);
    assert_eq!(p.field.as_deref(), Some("meta/episode_ends"));
    assert_eq!(p.frame, Some(25));
    let msg = err.to_string();
    for name in ["action", "state", "timestamp", "action_rotvec"] {
        assert!(msg.contains(name), "{msg}");
    }
}

#[test]
fn a_shape_beyond_any_episode_is_refused_before_allocating() {
    let task = TaskSpec::builtin("click_mouse").unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("click_mouse/episode_000000");
    write(&dir, &synth::episode(task, 10, 3));
    let zarray = dir.join("replay.zarr/data/state/.zarray");
    let mut meta: serde_json::Value =
        serde_json::from_slice(&fs_err::read(&zarray).unwrap()).unwrap();
    meta["shape"] = serde_json::json!([u64::MAX / 2, 31]);
    meta["chunks"] = serde_json::json!([u64::MAX / 2, 31]);
    fs_err::write(&zarray, meta.to_string()).unwrap();
    let err = raw::read_raw_episode(&dir, task).unwrap_err();
    let FormatError::Input(p) = &err else {
        panic!("{err}")
    };
    assert_eq!(p.code, ProblemCode::WrongDimensions, "{err}");
    assert_eq!(p.field.as_deref(), Some("state"));
}
