//! The settings that decide an augment output's bytes, written once into the output
//! folder (`augment_settings.json`) and checked by every later run into it (a resume,
//! a shard, the finalize): a run with other settings is refused, naming what differs
//! (`--overwrite` starts clean instead). The settings cover each task's whole scene (every
//! file it loads, by content) and the versions of the programs that decide the bytes.
//! Each replay's record also carries the content hash of its source episode, so two
//! datasets whose episodes share names never mix.

use std::collections::BTreeMap;
use std::path::Path;

use dexjoco_core::{Episode, TaskSpec};
use dexjoco_render::warp::WarpOptions;
use dexjoco_render::{Geometry, RenderQuality, RenderSettings, RendererKind};
use dexjoco_sim::SceneSource;
use dexjoco_sim::scene_files::SceneHashes;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::config::{AugmentConfig, SETTINGS_FILE, VideoEncoding};
use crate::error::AugmentError;
use crate::provenance::ToolVersions;
use dexjoco_render::randomize::CameraPool;

/// Format name of the settings file.
const FORMAT: &str = "dexjoco-data/augment-settings";

/// The most differences named (a folder made before the scene's files were hashed differs
/// in every one of them).
const MAX_DIFFERENCES: usize = 12;

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
    /// The renderer (written only when not OpenGL, so folders made before the option read
    /// the same): a folder is made by one renderer, a resume with another is refused.
    #[serde(default, skip_serializing_if = "RendererKind::is_opengl")]
    pub renderer: RendererKind,
    /// The Warp renderer's rays per pixel and axis, when given (`--warp-supersample`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warp_supersample: Option<u32>,
    /// The Warp renderer's device as asked for (`--warp-device`: `auto`, `cpu`,
    /// `cuda:N`): a CPU and a GPU ray tracer may differ in last bits, so a resume on
    /// another is refused (`auto` resolves per machine: each replay's record names the
    /// device that drew it, and the report warns when they differ).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub warp_device: Option<String>,
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
    /// The videos' encoding (files written before it was recorded: the legacy one).
    #[serde(default = "VideoEncoding::legacy")]
    pub video: VideoEncoding,
    /// Where scenes come from (`built-in` or the scene folder).
    pub scene: String,
    /// Per task: SHA-256 of its scene file (the composed built-in XML, or the scene pack's
    /// file) and of every other file the scene loads, of its camera pool's poses, and of
    /// its spec.
    pub tasks: BTreeMap<String, TaskInputs>,
    /// The programs that decide the bytes: this build, MuJoCo, ffmpeg and x264 (each "not
    /// recorded" in folders made before they were).
    #[serde(default)]
    pub versions: ToolVersions,
}

/// The per-task inputs of an output's bytes, as content hashes.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct TaskInputs {
    /// The scene file.
    pub scene: String,
    /// Every other file the scene loads (included MJCF files, meshes, height fields,
    /// skins, textures), by path relative to the scene folder (`missing` for a name that
    /// resolves to no file); none for a built-in scene, which is all in its XML.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub scene_files: BTreeMap<String, String>,
    /// The camera pool's poses (and where they came from).
    pub camera_pool: String,
    /// The task spec.
    pub spec: String,
}

fn sha(bytes: &[u8]) -> String {
    format!("sha256:{:x}", Sha256::digest(bytes))
}

/// The content hashes of a task's scene as this run loads it.
pub(crate) fn scene_hash(
    source: &SceneSource,
    spec: &TaskSpec,
) -> Result<SceneHashes, AugmentError> {
    dexjoco_sim::scene_files::scene_hash(source, spec).map_err(|source| AugmentError::Sim {
        episode: spec.id.clone(),
        source: source.into(),
    })
}

/// SHA-256 of an episode's content: task, id, every array's values bit for bit, and its
/// own instruction when it has one (one that differs from `spec`'s prompt; an episode
/// without one hashes as before instructions travelled), so a changed instruction is a
/// changed source.
pub(crate) fn episode_hash(ep: &Episode, spec: &TaskSpec) -> String {
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
    if let Some(instruction) = dexjoco_formats::raw::own_instruction(ep, spec) {
        h.update(b"instruction");
        h.update((instruction.len() as u64).to_le_bytes());
        h.update(instruction.as_bytes());
    }
    format!("sha256:{:x}", h.finalize())
}

impl OutputSettings {
    /// The settings of `config` with each task's inputs and this process's versions.
    /// Every setting is named here, fingerprinted or not (and why not), so a new one does
    /// not compile until it is decided.
    pub(crate) fn of<'a>(
        config: &AugmentConfig,
        tasks: impl IntoIterator<Item = (String, SceneHashes, &'a CameraPool, String)>,
    ) -> Self {
        let AugmentConfig {
            seed,
            settings,
            cameras,
            depth,
            max_frames,
            extend_steps,
            dynamics,
            scene,
            video,
            // By content instead: each replay records its source episode's hash.
            inputs: _,
            out: _,
            // More replays add folders; the ones there keep their bytes.
            replays: _,
            // The specs it gives are hashed per task (`tasks.<task>.spec`).
            tasks_dir: _,
            // Its poses are hashed per task (`tasks.<task>.camera_pool`).
            camera_pool: _,
            // Keeps or drops whole replays; a kept one has the same bytes either way.
            keep_failed: _,
            // The reference approach, proven to give the same bytes.
            resimulate_per_replay: _,
            // A file beside the replays, made again by every unsharded run.
            contact_sheet: _,
            // The shards of a split write the bytes of one run.
            shard: _,
            overwrite: _,
            renderer,
            warp:
                WarpOptions {
                    supersample,
                    // The worker's Python is checked to have the pinned versions.
                    python: _,
                    device,
                    // Each world is one image: the batch size leaves the bytes alone.
                    worlds: _,
                },
        } = config;
        let RenderSettings {
            width,
            height,
            quality,
            geometry,
            // Augment renders depth as `config.depth` says.
            depth: _,
        } = settings;
        Self {
            format: FORMAT.into(),
            version: 1,
            seed: *seed,
            width: *width,
            height: *height,
            quality: *quality,
            geometry: *geometry,
            renderer: *renderer,
            warp_supersample: supersample.filter(|_| *renderer == RendererKind::Warp),
            warp_device: (*renderer == RendererKind::Warp).then(|| device.clone()),
            cameras: cameras.clone(),
            depth: *depth,
            max_frames: *max_frames,
            extend_steps: *extend_steps,
            dynamics: *dynamics,
            video: *video,
            // The folder as an absolute path, so `xmls` and `/abs/xmls` are one folder.
            scene: match scene {
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
                    let inputs = TaskInputs {
                        scene: scene.scene,
                        scene_files: scene.files,
                        camera_pool,
                        spec,
                    };
                    (task, inputs)
                })
                .collect(),
            versions: crate::provenance::current_versions().clone(),
        }
    }

    /// SHA-256 of a task spec as this run uses it.
    pub(crate) fn spec_hash(spec: &TaskSpec) -> String {
        sha(&serde_json::to_vec(spec).expect("specs serialize"))
    }

    /// What differs from `other` (the settings an output was made with), in words:
    /// `setting: now (was before)`, content hashes shortened, at most
    /// 12 lines (the last says how many more).
    pub fn differences(&self, other: &Self) -> Vec<String> {
        let mut out = Vec::new();
        let a = serde_json::to_value(self).expect("serializes");
        let b = serde_json::to_value(other).expect("serializes");
        diff("", &a, &b, &mut out);
        if out.len() > MAX_DIFFERENCES {
            let more = out.len() - (MAX_DIFFERENCES - 1);
            out.truncate(MAX_DIFFERENCES - 1);
            out.push(format!("and {more} more"));
        }
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
        (a, b) if a != b => out.push(format!("{prefix}: {} (was {})", shown(a), shown(b))),
        _ => {}
    }
}

/// A leaf as the differences show it: a content hash by its first 12 hex digits.
fn shown(value: &serde_json::Value) -> String {
    match value.as_str() {
        Some(h) if h.starts_with("sha256:") && h.len() > 19 => match h.get(..19) {
            Some(short) => format!("\"{short}…\""),
            None => value.to_string(),
        },
        _ => value.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(size: u32) -> AugmentConfig {
        AugmentConfig {
            replays: 1,
            settings: RenderSettings {
                width: size,
                height: size,
                ..RenderSettings::default()
            },
            contact_sheet: false,
            ..AugmentConfig::new(Vec::new(), "o")
        }
    }

    /// Scene hashes: the scene file's `scene`, and `files` with one hash each.
    fn hashes(scene: &str, files: &[(&str, &str)]) -> SceneHashes {
        SceneHashes {
            scene: scene.into(),
            files: files
                .iter()
                .map(|(f, h)| ((*f).to_owned(), (*h).to_owned()))
                .collect(),
        }
    }

    #[test]
    fn an_episode_s_own_instruction_is_part_of_its_hash() {
        let spec = dexjoco_core::TaskSpec::builtin("click_mouse").expect("built-in task");
        let mut ep = dexjoco_core::synth::episode(spec, 5, 1);
        ep.prompt = String::new();
        let plain = episode_hash(&ep, spec);
        // The spec's own prompt is no instruction of the episode's: the hash is unchanged.
        ep.prompt = spec.prompt.clone();
        assert_eq!(episode_hash(&ep, spec), plain);
        ep.prompt = "Click the mouse twice".into();
        let instructed = episode_hash(&ep, spec);
        assert_ne!(instructed, plain);
        ep.prompt = "Click the mouse once".into();
        assert_ne!(episode_hash(&ep, spec), instructed);
    }

    #[test]
    fn differences_name_the_setting_and_both_values() {
        let pool = dexjoco_render::randomize::builtin_pool(dexjoco_core::ArmSetup::SingleArm);
        let task = || [("t".to_owned(), hashes("s", &[]), &pool, "x".to_owned())];
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

    /// Each fingerprinted setting (`of` names every setting and decides which are) is
    /// named when it changes, as are each task's inputs and the versions: a resume that
    /// changes any one of them is refused, naming it.
    #[test]
    fn every_byte_changing_setting_is_named() {
        let pool = dexjoco_render::randomize::builtin_pool(dexjoco_core::ArmSetup::SingleArm);
        let other_pool = dexjoco_render::randomize::builtin_pool(dexjoco_core::ArmSetup::Bimanual);
        let scenes = tempfile::tempdir().unwrap();
        let base = config(64);
        let files = [("robot.xml", "sha256:1"), ("mesh.stl", "sha256:2")];
        let task = |scene: &str, pool, spec: &str| {
            [("t".to_owned(), hashes(scene, &files), pool, spec.to_owned())]
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
            ("video", changed(&base, |c| c.video.keyframe_interval = 2)),
            (
                "renderer",
                changed(&base, |c| c.renderer = dexjoco_render::RendererKind::Warp),
            ),
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
            (
                "tasks.t.scene_files.robot.xml",
                OutputSettings::of(
                    &base,
                    [(
                        "t".to_owned(),
                        hashes("s", &[("robot.xml", "sha256:3"), files[1]]),
                        &pool,
                        "x".to_owned(),
                    )],
                ),
            ),
            (
                "versions.ffmpeg",
                OutputSettings {
                    versions: ToolVersions {
                        ffmpeg: "7.1".into(),
                        ..was.versions.clone()
                    },
                    ..was.clone()
                },
            ),
        ]);
        for (key, now) in changed {
            let d = now.differences(&was);
            // The Warp renderer brings its device (the one asked for) along.
            let named = |l: &String| {
                l.starts_with(key) || (key == "renderer" && l.starts_with("warp_device"))
            };
            assert!(
                !d.is_empty() && d.iter().all(named),
                "changing {key} gives {d:?}"
            );
        }
    }

    /// A Warp folder records the device asked for: a resume on another is refused (CPU
    /// and GPU ray tracers may differ in last bits); an OpenGL folder records none.
    #[test]
    fn the_warp_device_is_part_of_a_warp_folders_settings() {
        let pool = dexjoco_render::randomize::builtin_pool(dexjoco_core::ArmSetup::SingleArm);
        let task = || [("t".to_owned(), hashes("s", &[]), &pool, "x".to_owned())];
        let warp = |device: &str| {
            let mut c = config(64);
            c.renderer = dexjoco_render::RendererKind::Warp;
            c.warp.device = device.into();
            OutputSettings::of(&c, task())
        };
        let (cpu, gpu) = (warp("cpu"), warp("cuda:0"));
        assert_eq!(
            gpu.differences(&cpu),
            ["warp_device: \"cuda:0\" (was \"cpu\")"]
        );
        let mut gl = config(64);
        gl.warp.device = "cuda:0".into();
        assert_eq!(OutputSettings::of(&gl, task()).warp_device, None);
    }

    #[test]
    fn one_scene_folder_named_two_ways_is_one_setting() {
        let pool = dexjoco_render::randomize::builtin_pool(dexjoco_core::ArmSetup::SingleArm);
        let dir = tempfile::tempdir().unwrap();
        fs_err::create_dir(dir.path().join("xmls")).unwrap();
        let task = || [("t".to_owned(), hashes("s", &[]), &pool, "x".to_owned())];
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
