//! Every episode container round trips through its trait: an episode written to a
//! temporary folder is probed as that container's own (and no other's), found by
//! discovery, and read back bit for bit.

use std::path::{Path, PathBuf};

use dexjoco_core::{Episode, TaskSet, TaskSpec, synth};
use dexjoco_formats::episodes::CONTAINERS;
use dexjoco_formats::{EpisodeContainer, EpisodeMeta, discover};

/// Where `container` puts episode `id` of `task` under `root`.
fn episode_path(container: &dyn EpisodeContainer, root: &Path, task: &str, id: &str) -> PathBuf {
    let dir = root.join(task);
    match container.extension() {
        Some(ext) => dir.join(format!("{id}.{ext}")),
        None => dir.join(id),
    }
}

fn assert_same_episode(written: &Episode, read: &Episode, container: &str) {
    assert_eq!(read.id, written.id, "{container}");
    assert_eq!(read.task, written.task, "{container}");
    assert_eq!(read.prompt, written.prompt, "{container}");
    assert_eq!(read.fps.to_bits(), written.fps.to_bits(), "{container}");
    assert_eq!(
        read.arrays.keys().collect::<Vec<_>>(),
        written.arrays.keys().collect::<Vec<_>>(),
        "{container}"
    );
    for (name, a) in &written.arrays {
        let b = &read.arrays[name];
        assert_eq!(
            (a.len(), a.width()),
            (b.len(), b.width()),
            "{container}: {name}"
        );
        for (x, y) in a.as_slice().iter().zip(b.as_slice()) {
            assert_eq!(x.to_bits(), y.to_bits(), "{container}: {name}: {x} vs {y}");
        }
    }
}

#[test]
fn every_container_writes_probes_and_reads_back_its_episode() {
    let tasks = TaskSet::builtin();
    for task_id in ["click_mouse", "bimanual_hanoi"] {
        let task = TaskSpec::builtin(task_id).unwrap();
        let mut episode = synth::episode(task, 25, 7);
        episode.id = "episode_000000".into();
        for container in CONTAINERS {
            let tmp = tempfile::tempdir().unwrap();
            let path = episode_path(container, tmp.path(), task_id, &episode.id);
            container
                .write(&path, &episode, task, &EpisodeMeta::default())
                .unwrap();

            for other in CONTAINERS {
                assert_eq!(
                    other.probe(&path),
                    other.kind() == container.kind(),
                    "{} probing a {} episode",
                    other.name(),
                    container.name()
                );
            }
            let found = discover(&[tmp.path().to_owned()], None).unwrap();
            assert_eq!(found.len(), 1, "{}: {found:?}", container.name());
            assert_eq!((&found[0].path, found[0].kind), (&path, container.kind()));

            let read = found[0].read(tasks).unwrap();
            assert_same_episode(&episode, &read.episode, container.name());
            let direct = container.read(&path, tasks, Default::default()).unwrap();
            assert_same_episode(&episode, &direct.episode, container.name());
        }
    }
}
