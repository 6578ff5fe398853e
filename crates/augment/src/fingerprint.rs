//! The settings that decide an augment output's bytes, written once into the output
//! folder (`augment_settings.json`) and checked by every later run into it (a resume,
//! a shard, the finalize): a run with other settings is refused, naming what differs
//! (`--overwrite` starts clean instead). Each replay's record also carries the content
//! hash of its source episode, so two datasets whose episodes share names never mix.

use std::collections::BTreeMap;
use std::path::Path;

use dexjoco_core::{Episode, TaskSpec};
use dexjoco_sim::{Geometry, RenderQuality, SceneSource};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::config::{AugmentConfig, SETTINGS_FILE};
use crate::error::AugmentError;
use crate::randomize::CameraPool;

/// Format name of the settings file.
const FORMAT: &str = "dexjoco-data/augment-settings";

/// What decides the bytes of every replay in an output folder.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OutputSettings {
    /// Always `dexjoco-data/augment-settings`.
    pub format: String,
    /// Format version.
    pub version: u32,
    /// Global seed.
    pub seed: u64,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Render quality.
    pub quality: RenderQuality,
    /// The renderer's meshes (written only when not the full ones, so folders made before
    /// the option read the same).
    #[serde(default, skip_serializing_if = "Geometry::is_full")]
    pub geometry: Geometry,
    /// Fixed cameras rendered besides the third-person view.
    pub cameras: Vec<String>,
    /// Depth archives written.
    pub depth: bool,
    /// Recorded frames cut (`--max-frames`).
    pub max_frames: Option<usize>,
    /// `--extend-steps`.
    pub extend_steps: usize,
    /// Dynamics randomized.
    pub dynamics: bool,
    /// Where scenes come from (`built-in` or the scene folder).
    pub scene: String,
    /// Per task: SHA-256 of its scene file (the composed built-in XML, or the scene pack's
    /// file), of its camera pool's poses, and of its spec.
    pub tasks: BTreeMap<String, TaskInputs>,
}

/// The per-task inputs of an output's bytes, as content hashes.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TaskInputs {
    /// The scene file.
    pub scene: String,
    /// The camera pool's poses (and where they came from).
    pub camera_pool: String,
    /// The task spec.
    pub spec: String,
}

fn sha(bytes: &[u8]) -> String {
    format!("sha256:{:x}", Sha256::digest(bytes))
}

/// SHA-256 of a task's scene file as this run loads it.
pub(crate) fn scene_hash(source: &SceneSource, spec: &TaskSpec) -> Result<String, AugmentError> {
    match source {
        SceneSource::BuiltIn => {
            let xml =
                dexjoco_sim::builtin::scene_xml(spec).map_err(|source| AugmentError::Sim {
                    episode: spec.id.clone(),
                    source,
                })?;
            Ok(sha(xml.as_bytes()))
        }
        SceneSource::Dir(dir) => {
            let path = dir.join(&spec.scene);
            let bytes = fs_err::read(&path).map_err(crate::error::io_err("read", &path))?;
            Ok(sha(&bytes))
        }
    }
}

/// SHA-256 of an episode's content: task, id and every array's values bit for bit.
pub(crate) fn episode_hash(ep: &Episode) -> String {
    let mut h = Sha256::new();
    for part in [ep.task.as_bytes(), ep.id.as_bytes()] {
        h.update((part.len() as u64).to_le_bytes());
        h.update(part);
    }
    for (name, a) in &ep.arrays {
        h.update((name.len() as u64).to_le_bytes());
        h.update(name.as_bytes());
        h.update((a.width() as u64).to_le_bytes());
        h.update((a.len() as u64).to_le_bytes());
        for v in a.as_slice() {
            h.update(v.to_bits().to_le_bytes());
        }
    }
    format!("sha256:{:x}", h.finalize())
}

impl OutputSettings {
    /// The settings of `config` with each task's inputs.
    pub(crate) fn of<'a>(
        config: &AugmentConfig,
        tasks: impl IntoIterator<Item = (String, String, &'a CameraPool, String)>,
    ) -> Self {
        Self {
            format: FORMAT.into(),
            version: 1,
            seed: config.seed,
            width: config.settings.width,
            height: config.settings.height,
            quality: config.settings.quality,
            geometry: config.settings.geometry,
            cameras: config.cameras.clone(),
            depth: config.depth,
            max_frames: config.max_frames,
            extend_steps: config.extend_steps,
            dynamics: config.dynamics,
            // The folder as an absolute path, so `xmls` and `/abs/xmls` are one folder.
            scene: match &config.scene {
                SceneSource::BuiltIn => "built-in".into(),
                SceneSource::Dir(d) => d
                    .canonicalize()
                    .unwrap_or_else(|_| d.clone())
                    .display()
                    .to_string(),
            },
            tasks: tasks
                .into_iter()
                .map(|(task, scene, pool, spec)| {
                    let poses = serde_json::to_vec(&pool.poses).expect("poses serialize");
                    let camera_pool = format!("{} {}", pool.source, sha(&poses));
                    (
                        task,
                        TaskInputs {
                            scene,
                            camera_pool,
                            spec,
                        },
                    )
                })
                .collect(),
        }
    }

    /// SHA-256 of a task spec as this run uses it.
    pub(crate) fn spec_hash(spec: &TaskSpec) -> String {
        sha(&serde_json::to_vec(spec).expect("specs serialize"))
    }

    /// What differs from `other` (the settings an output was made with), in words.
    pub fn differences(&self, other: &Self) -> Vec<String> {
        let mut out = Vec::new();
        let a = serde_json::to_value(self).expect("serializes");
        let b = serde_json::to_value(other).expect("serializes");
        diff("", &a, &b, &mut out);
        out
    }

    /// Checks `out`'s settings file against these settings: none yet (written now), the
    /// same (resume), or other ones (refused, naming the differences).
    pub(crate) fn check_or_write(&self, out: &Path) -> Result<(), AugmentError> {
        let path = out.join(SETTINGS_FILE);
        let bytes = serde_json::to_vec_pretty(self).expect("serializes");
        match fs_err::read(&path) {
            Ok(old) => {
                let old: Self = serde_json::from_slice(&old).map_err(|e| {
                    AugmentError::Input(format!(
                        "'{}' is not an augment settings file ({e}): remove it, or use another --out",
                        path.display()
                    ))
                })?;
                let diff = self.differences(&old);
                if diff.is_empty() {
                    return Ok(());
                }
                Err(AugmentError::SettingsChanged {
                    out: out.to_owned(),
                    differences: diff,
                })
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                dexjoco_formats::write_atomic(&path, &bytes)?;
                Ok(())
            }
            Err(e) => Err(crate::error::io_err("read", &path)(e)),
        }
    }
}

/// Leaf-by-leaf differences of two JSON values, as `key: now (was before)`.
fn diff(prefix: &str, now: &serde_json::Value, was: &serde_json::Value, out: &mut Vec<String>) {
    use serde_json::Value;
    match (now, was) {
        (Value::Object(a), Value::Object(b)) => {
            let keys: std::collections::BTreeSet<&String> = a.keys().chain(b.keys()).collect();
            for k in keys {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                match (a.get(k), b.get(k)) {
                    (Some(x), Some(y)) => diff(&key, x, y, out),
                    (Some(x), None) => out.push(format!("{key}: {x} (was absent)")),
                    (None, Some(y)) => out.push(format!("{key}: absent (was {y})")),
                    (None, None) => {}
                }
            }
        }
        (a, b) if a != b => out.push(format!("{prefix}: {a} (was {b})")),
        _ => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(size: u32) -> AugmentConfig {
        AugmentConfig {
            inputs: Vec::new(),
            out: "o".into(),
            replays: 1,
            seed: 0,
            tasks_dir: None,
            scene: SceneSource::BuiltIn,
            camera_pool: None,
            cameras: Vec::new(),
            settings: dexjoco_sim::RenderSettings {
                width: size,
                height: size,
                quality: RenderQuality::FAST,
                depth: false,
                geometry: Geometry::Full,
            },
            keep_failed: false,
            max_frames: None,
            resimulate_per_replay: false,
            contact_sheet: false,
            depth: false,
            dynamics: false,
            extend_steps: 30,
            shard: None,
            overwrite: false,
        }
    }

    #[test]
    fn differences_name_the_setting_and_both_values() {
        let pool = crate::randomize::builtin_pool(dexjoco_core::ArmSetup::SingleArm);
        let task = || [("t".to_owned(), "s".to_owned(), &pool, "x".to_owned())];
        let a = OutputSettings::of(&config(64), task());
        let b = OutputSettings::of(&config(224), task());
        assert!(a.differences(&a).is_empty());
        assert_eq!(
            a.differences(&b),
            ["height: 64 (was 224)", "width: 64 (was 224)"]
        );
    }

    /// `base` with one change.
    fn changed(base: &AugmentConfig, change: impl FnOnce(&mut AugmentConfig)) -> AugmentConfig {
        let mut c = base.clone();
        change(&mut c);
        c
    }

    /// Every setting that changes a replay's bytes is part of the fingerprint: a resume
    /// that changes any one of them is refused, naming it.
    #[test]
    fn every_byte_changing_setting_is_named() {
        let pool = crate::randomize::builtin_pool(dexjoco_core::ArmSetup::SingleArm);
        let other_pool = crate::randomize::builtin_pool(dexjoco_core::ArmSetup::Bimanual);
        let scenes = tempfile::tempdir().unwrap();
        let base = config(64);
        let task = |scene: &str, pool, spec: &str| {
            [("t".to_owned(), scene.to_owned(), pool, spec.to_owned())]
        };
        let was = OutputSettings::of(&base, task("s", &pool, "x"));
        let configs: Vec<(&str, AugmentConfig)> = vec![
            ("seed", changed(&base, |c| c.seed = 1)),
            (
                "quality",
                changed(&base, |c| c.settings.quality = RenderQuality::PAPER),
            ),
            (
                "geometry",
                changed(&base, |c| c.settings.geometry = Geometry::Light),
            ),
            (
                "cameras",
                changed(&base, |c| c.cameras = vec!["front".into()]),
            ),
            ("depth", changed(&base, |c| c.depth = true)),
            ("max_frames", changed(&base, |c| c.max_frames = Some(3))),
            ("extend_steps", changed(&base, |c| c.extend_steps = 0)),
            ("dynamics", changed(&base, |c| c.dynamics = true)),
            (
                "scene",
                changed(&base, |c| c.scene = SceneSource::Dir(scenes.path().into())),
            ),
        ];
        let mut changed: Vec<(&str, OutputSettings)> = configs
            .iter()
            .map(|(key, c)| (*key, OutputSettings::of(c, task("s", &pool, "x"))))
            .collect();
        changed.extend([
            (
                "tasks.t.scene",
                OutputSettings::of(&base, task("other scene", &pool, "x")),
            ),
            (
                "tasks.t.camera_pool",
                OutputSettings::of(&base, task("s", &other_pool, "x")),
            ),
            (
                "tasks.t.spec",
                OutputSettings::of(&base, task("s", &pool, "other spec")),
            ),
        ]);
        for (key, now) in changed {
            let d = now.differences(&was);
            assert!(
                !d.is_empty() && d.iter().all(|l| l.starts_with(key)),
                "changing {key} gives {d:?}"
            );
        }
    }

    #[test]
    fn one_scene_folder_named_two_ways_is_one_setting() {
        let pool = crate::randomize::builtin_pool(dexjoco_core::ArmSetup::SingleArm);
        let dir = tempfile::tempdir().unwrap();
        fs_err::create_dir(dir.path().join("xmls")).unwrap();
        let task = || [("t".to_owned(), "s".to_owned(), &pool, "x".to_owned())];
        let direct = AugmentConfig {
            scene: SceneSource::Dir(dir.path().join("xmls")),
            ..config(64)
        };
        let roundabout = AugmentConfig {
            scene: SceneSource::Dir(dir.path().join("xmls/../xmls")),
            ..config(64)
        };
        let a = OutputSettings::of(&direct, task());
        let b = OutputSettings::of(&roundabout, task());
        assert!(a.differences(&b).is_empty(), "{:?}", a.differences(&b));
    }
}
