//! An episode's own language instruction travels with it: a raw folder keeps it as the
//! `instruction` attribute of `replay.zarr/.zattrs` (zarr-python 2 still opens the store
//! and reads every array), reads it back as the episode's prompt, and writes nothing
//! more than the recorder when the episode has none of its own; an MCAP log's empty
//! prompt is no instruction.

use std::path::Path;

use dexjoco_core::{Episode, TaskSet, TaskSpec, synth};
use dexjoco_formats::mcap::McapLog;
use dexjoco_formats::raw::{self, RawFolder};
use dexjoco_formats::{EpisodeContainer, EpisodeMeta, ReadOptions};

fn click_mouse(prompt: &str) -> (Episode, &'static TaskSpec) {
    let task = TaskSpec::builtin("click_mouse").unwrap();
    let mut ep = synth::episode(task, 9, 3);
    ep.id = "episode_000000".into();
    ep.prompt = prompt.into();
    (ep, task)
}

fn read_raw(dir: &Path) -> Episode {
    RawFolder
        .read(dir, TaskSet::builtin(), ReadOptions::default())
        .unwrap()
        .episode
}

#[test]
fn a_raw_folder_keeps_the_episodes_instruction_and_zarr_python_opens_it() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("click_mouse/episode_000000");
    let (ep, task) = click_mouse("Type password two on the iPad | then stop");
    RawFolder
        .write(&dir, &ep, task, &EpisodeMeta::default())
        .unwrap();
    assert_eq!(read_raw(&dir).prompt, ep.prompt);

    let dir_arg = dir.to_str().unwrap();
    let py = dexjoco_testkit::run_python_json("zarr_root_attrs.py", &[dir_arg]);
    assert_eq!(py["attrs"], serde_json::json!({"instruction": ep.prompt}));
    assert_eq!(py["shapes"]["data/action"], serde_json::json!([9, 23]));
    assert_eq!(py["shapes"]["meta/episode_ends"], serde_json::json!([1]));
    // The DexJoCo tools' reading (every array, values as written) is unchanged.
    let arrays = dexjoco_testkit::run_python_json("read_raw_episode.py", &[dir_arg]);
    let action = arrays["arrays"]["data/action"]["values"]
        .as_array()
        .unwrap();
    assert_eq!(action.len(), 9 * 23);
    assert_eq!(action[0].as_f64(), Some(ep.arrays["action"].as_slice()[0]));
}

#[test]
fn no_instruction_of_its_own_writes_what_the_recorder_writes() {
    let tmp = tempfile::tempdir().unwrap();
    let (ep, task) = click_mouse("");
    let recorder = tmp.path().join("recorder/click_mouse/episode_000000");
    raw::write_replay_zarr(&recorder, &ep).unwrap();
    let want = dexjoco_testkit::file_tree(&recorder);
    for prompt in ["", "  ", task.prompt.as_str()] {
        let (ep, _) = click_mouse(prompt);
        let dir = tmp
            .path()
            .join(format!("{}/click_mouse/episode_000000", prompt.len()));
        RawFolder
            .write(&dir, &ep, task, &EpisodeMeta::default())
            .unwrap();
        assert_eq!(dexjoco_testkit::file_tree(&dir), want, "prompt {prompt:?}");
        assert_eq!(read_raw(&dir).prompt, task.prompt, "prompt {prompt:?}");
    }
}

#[test]
fn an_instruction_that_is_not_a_text_is_an_error_naming_file_and_attribute() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("click_mouse/episode_000000");
    let (ep, task) = click_mouse("");
    raw::write_replay_zarr(&dir, &ep).unwrap();
    let attrs = dir.join("replay.zarr/.zattrs");
    fs_err::write(&attrs, r#"{"instruction": 3}"#).unwrap();
    let err = RawFolder
        .read(&dir, TaskSet::builtin(), ReadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains(".zattrs") && err.contains("'instruction'") && err.contains("not a text"),
        "{err}"
    );
    // Other attributes (a tool's own) are read past.
    fs_err::write(&attrs, r#"{"recorded_by": "someone"}"#).unwrap();
    assert_eq!(read_raw(&dir).prompt, task.prompt);
}

#[test]
fn an_mcap_logs_empty_prompt_is_no_instruction() {
    let tmp = tempfile::tempdir().unwrap();
    for (prompt, want) in [("", None), ("password two", Some("password two"))] {
        let (ep, task) = click_mouse(prompt);
        let file = tmp.path().join(format!("{}.mcap", prompt.len()));
        McapLog
            .write(&file, &ep, task, &EpisodeMeta::default())
            .unwrap();
        let read = McapLog
            .read(&file, TaskSet::builtin(), ReadOptions::default())
            .unwrap()
            .episode;
        assert_eq!(read.prompt, want.unwrap_or(&task.prompt));
    }
}
