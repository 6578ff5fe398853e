//! What to take from each episode: the selection config, modelled on the DexJoCo
//! reference converter's `selected_data.yaml` / `slice_config.yaml` /
//! `language_instructions.yaml` (which [`Selection::from_reference_dir`] reads as they are).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::ConvertError;

/// Which action array becomes the dataset's `action`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActionSource {
    /// `action_rotvec` (per arm xyz, rotation vector, hand16): what the reference uses.
    #[default]
    ActionRotvec,
    /// `action` (per arm xyz, quaternion wxyz, hand16).
    Action,
}

impl ActionSource {
    /// The episode array name.
    pub fn array_name(self) -> &'static str {
        match self {
            Self::ActionRotvec => dexjoco_core::Episode::ACTION_ROTVEC,
            Self::Action => dexjoco_core::Episode::ACTION,
        }
    }
}

/// A Python-style slice `[start, stop]` of columns; `null` (None) means open. Negative
/// values count from the end, as in Python.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct ColumnSlice(pub Option<i64>, pub Option<i64>);

impl ColumnSlice {
    /// The column range this slice selects out of `width` columns (Python semantics).
    pub fn range(self, width: usize) -> std::ops::Range<usize> {
        let w = width as i64;
        let fix = |v: i64| if v < 0 { (w + v).max(0) } else { v.min(w) } as usize;
        let start = self.0.map_or(0, fix);
        let stop = self.1.map_or(width, fix);
        start..stop.max(start)
    }
}

/// What to take from the episodes of one task.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TaskSelection {
    /// The action array (default `action_rotvec`).
    #[serde(default)]
    pub action: ActionSource,
    /// Columns of `state` to keep (default: the proprioceptive part, `[null, 23]` for one
    /// arm and `[null, 46]` for two, inferred from the action width).
    #[serde(default)]
    pub state: Option<ColumnSlice>,
    /// Output camera name -> raw camera name (default: every camera, same name).
    #[serde(default)]
    pub cameras: BTreeMap<String, String>,
}

/// The whole selection: per-task choices, instructions, excluded episodes.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Selection {
    /// Used for tasks not listed in `tasks`.
    #[serde(default)]
    pub default: TaskSelection,
    /// Per task id.
    #[serde(default)]
    pub tasks: BTreeMap<String, TaskSelection>,
    /// Task id -> language instruction (overrides the episode's own instruction and the
    /// task spec's prompt).
    #[serde(default)]
    pub instructions: BTreeMap<String, String>,
    /// Task id -> other ways to say its instruction (the `task_aug` rows of LeRobot
    /// v3.0's language columns; overrides the task spec's `prompt_variants`).
    #[serde(default)]
    pub prompt_variants: BTreeMap<String, Vec<String>>,
    /// Episode ids to leave out.
    #[serde(default)]
    pub bad_episodes: BTreeSet<String>,
    /// Skip static leading frames by the reference converter's rule (default true).
    #[serde(default = "yes")]
    pub skip_static_frames: bool,
    /// Multi-task merge of one-arm and two-arm tasks: one-arm episodes are laid into the
    /// right-arm slots of the two-arm layout (see [`crate::merge`]).
    #[serde(default)]
    pub merge_bimanual: bool,
}

fn yes() -> bool {
    true
}

/// Reads a config file: TOML (`.toml`) or YAML (anything else); a parse error names the
/// file.
fn read_config<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T, ConvertError> {
    let text = fs_err::read_to_string(path)?;
    let parsed = if path.extension().is_some_and(|e| e == "toml") {
        toml::from_str(&text).map_err(|e| e.to_string())
    } else {
        serde_norway::from_str(&text).map_err(|e| e.to_string())
    };
    parsed.map_err(|message| ConvertError::Config {
        path: path.to_path_buf(),
        message,
    })
}

impl Default for Selection {
    fn default() -> Self {
        Self {
            default: TaskSelection::default(),
            tasks: BTreeMap::new(),
            instructions: BTreeMap::new(),
            prompt_variants: BTreeMap::new(),
            bad_episodes: BTreeSet::new(),
            skip_static_frames: true,
            merge_bimanual: false,
        }
    }
}

impl Selection {
    /// The selection for a task.
    pub fn for_task(&self, task: &str) -> &TaskSelection {
        self.tasks.get(task).unwrap_or(&self.default)
    }

    /// The instruction of an episode of `task` whose prompt is `prompt`: the config's
    /// for the task, else the episode's prompt (its own instruction; the episode readers
    /// give an episode without one its task spec's prompt), else, when that is empty, the
    /// prompt of the task's built-in spec (`schemas/tasks/`, the reference converter's
    /// `language_instructions.yaml` text), else the task id.
    pub fn instruction(&self, task: &str, prompt: &str) -> String {
        if let Some(s) = self.instructions.get(task) {
            return s.clone();
        }
        if !prompt.trim().is_empty() {
            return prompt.to_owned();
        }
        dexjoco_core::TaskSpec::builtin(task).map_or_else(|| task.to_owned(), |s| s.prompt.clone())
    }

    /// The `task_aug` texts of an episode of `task` whose instruction is `instruction`:
    /// the instruction, then the task's prompt variants (this selection's, else its
    /// built-in spec's), each once.
    pub fn task_aug(&self, task: &str, instruction: &str) -> Vec<String> {
        let builtin = || dexjoco_core::TaskSpec::builtin(task).map(|s| &s.prompt_variants);
        let variants = self.prompt_variants.get(task).or_else(builtin);
        let mut out = vec![instruction.to_owned()];
        for v in variants.into_iter().flatten() {
            if !v.trim().is_empty() && !out.contains(v) {
                out.push(v.clone());
            }
        }
        out
    }

    /// The most `task_aug` texts an episode of any task named in this selection or
    /// built in can get (every episode's language slice is padded to one length).
    pub fn most_task_aug(&self) -> usize {
        let builtin = dexjoco_core::TaskSet::builtin().ids();
        // An empty instruction equals no variant: the count is an upper bound.
        self.prompt_variants
            .keys()
            .map(String::as_str)
            .chain(builtin)
            .map(|t| self.task_aug(t, "").len())
            .max()
            .unwrap_or(1)
    }

    /// Reads an instructions file (`--instructions`): TOML (`.toml`) or YAML, task id ->
    /// its prompt variants (a list of texts, or one text), into [`Self::prompt_variants`].
    pub fn load_prompt_variants(&mut self, path: &Path) -> Result<(), ConvertError> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Texts {
            One(String),
            Many(Vec<String>),
        }
        let map: BTreeMap<String, Texts> = read_config(path)?;
        for (task, texts) in map {
            let texts = match texts {
                Texts::One(t) => vec![t],
                Texts::Many(v) => v,
            };
            self.prompt_variants.insert(task, texts);
        }
        Ok(())
    }

    /// Reads a selection config: TOML (`.toml`) or YAML (anything else), with the fields
    /// of [`Selection`].
    pub fn load(path: &Path) -> Result<Self, ConvertError> {
        read_config::<Self>(path)?.check_names(path)
    }

    /// The selection when every output camera name is a name, not a path: it names the
    /// dataset's video folders and files ([`dexjoco_core::safe_name`]).
    fn check_names(self, path: &Path) -> Result<Self, ConvertError> {
        let all = std::iter::once(("default", &self.default))
            .chain(self.tasks.iter().map(|(t, s)| (t.as_str(), s)));
        for (task, selection) in all {
            for camera in selection.cameras.keys() {
                dexjoco_core::safe_name("output camera name", camera).map_err(|e| {
                    ConvertError::Config {
                        path: path.to_path_buf(),
                        message: format!("cameras of {task}: {e}"),
                    }
                })?;
            }
        }
        Ok(self)
    }

    /// Reads the DexJoCo reference converter's config folder as it is:
    /// `selected_data.yaml` (per task: cameras, action, state), `slice_config.yaml` (per
    /// task: `state: [null, 23]`) and `language_instructions.yaml` (task -> text), each
    /// optional.
    pub fn from_reference_dir(dir: &Path) -> Result<Self, ConvertError> {
        #[derive(Deserialize)]
        struct Selected {
            #[serde(default)]
            cameras: BTreeMap<String, String>,
            #[serde(default)]
            action: Option<ActionSource>,
            #[serde(default, rename = "state")]
            _state: Option<String>,
        }
        #[derive(Deserialize)]
        struct Sliced {
            #[serde(default)]
            state: Option<ColumnSlice>,
        }
        fn read<T: serde::de::DeserializeOwned>(path: PathBuf) -> Result<Option<T>, ConvertError> {
            if !path.is_file() {
                return Ok(None);
            }
            let text = fs_err::read_to_string(&path)?;
            serde_norway::from_str(&text)
                .map(Some)
                .map_err(|e| ConvertError::Config {
                    path,
                    message: e.to_string(),
                })
        }
        let mut sel = Self::default();
        let selected: Option<BTreeMap<String, Selected>> = read(dir.join("selected_data.yaml"))?;
        for (task, s) in selected.unwrap_or_default() {
            let t = sel.tasks.entry(task).or_default();
            t.cameras = s.cameras;
            t.action = s.action.unwrap_or_default();
        }
        let sliced: Option<BTreeMap<String, Sliced>> = read(dir.join("slice_config.yaml"))?;
        for (task, s) in sliced.unwrap_or_default() {
            sel.tasks.entry(task).or_default().state = s.state;
        }
        let instructions: Option<BTreeMap<String, String>> =
            read(dir.join("language_instructions.yaml"))?;
        sel.instructions = instructions.unwrap_or_default();
        sel.check_names(&dir.join("selected_data.yaml"))
    }
}

/// The first frame the reference converter keeps (static leading frames skipped); the
/// rule lives in `dexjoco-core` so that `stats --dataset` counts the same frames.
pub use dexjoco_core::first_moving_frame;

#[cfg(test)]
mod tests {
    use super::*;
    use dexjoco_core::FrameArray;

    #[test]
    fn python_slices() {
        assert_eq!(ColumnSlice(None, Some(23)).range(31), 0..23);
        assert_eq!(ColumnSlice(Some(-8), None).range(31), 23..31);
        assert_eq!(ColumnSlice(None, Some(40)).range(31), 0..31);
        assert_eq!(ColumnSlice(Some(5), Some(2)).range(31), 5..5);
    }

    #[test]
    fn static_leading_frames_follow_the_reference_rule() {
        let rows = |v: &[f64]| {
            FrameArray::from_rows(&v.iter().map(|x| vec![*x, 1.0]).collect::<Vec<_>>()).unwrap()
        };
        // repeats, then moves: start at the last repeat
        assert_eq!(
            first_moving_frame(&rows(&[3.0, 3.0, 3.0, 4.0, 5.0]), false),
            2
        );
        // moving from the start
        assert_eq!(first_moving_frame(&rows(&[1.0, 2.0]), false), 0);
        // never moves: keep everything
        assert_eq!(first_moving_frame(&rows(&[1.0, 1.0]), false), 0);
        // a change below float32's resolution moves only as recorded
        let tiny = rows(&[0.3, 0.3 + 1e-12, 0.3 + 2e-12, 0.4]);
        assert_eq!(first_moving_frame(&tiny, false), 0);
        assert_eq!(first_moving_frame(&tiny, true), 2);
        // all-zero rows before the first change: one further
        let z = FrameArray::from_rows(&[
            vec![0.0, 0.0],
            vec![0.0, 0.0],
            vec![0.5, 0.0],
            vec![0.6, 0.0],
        ])
        .unwrap();
        assert_eq!(first_moving_frame(&z, false), 2);
        assert_eq!(first_moving_frame(&z, true), 2);
    }

    #[test]
    fn reads_the_reference_converter_configs() {
        let dir = dexjoco_testkit::workspace_root()
            .join("../shared/dexjoco-upstream/converter-configs/multi_task");
        assert!(
            dir.is_dir(),
            "the reference converter configs are absent: {}",
            dir.display()
        );
        let sel = Selection::from_reference_dir(&dir).unwrap();
        let t = sel.for_task("bimanual_hanoi");
        assert_eq!(t.action, ActionSource::ActionRotvec);
        assert_eq!(t.cameras.get("base").map(String::as_str), Some("ego"));
        assert_eq!(
            sel.for_task("click_mouse").state,
            Some(ColumnSlice(None, Some(23)))
        );
        assert!(
            sel.instruction("water_plant", "")
                .starts_with("Grasp the watering can")
        );
        // The reference config names every task: its text wins over the episode's.
        assert!(
            sel.instruction("water_plant", "water it")
                .starts_with("Grasp the watering can")
        );
    }

    #[test]
    fn the_config_then_the_episode_then_the_spec_instructs() {
        let mut sel = Selection::default();
        let spec = dexjoco_core::TaskSpec::builtin("click_mouse").unwrap();
        assert_eq!(
            sel.instruction("click_mouse", "password two"),
            "password two"
        );
        assert_eq!(sel.instruction("click_mouse", " "), spec.prompt);
        assert_eq!(sel.instruction("my_task", ""), "my_task");
        sel.instructions
            .insert("click_mouse".into(), "result of 1+1".into());
        assert_eq!(
            sel.instruction("click_mouse", "password two"),
            "result of 1+1"
        );
    }

    #[test]
    fn toml_and_yaml_configs() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sel.toml");
        fs_err::write(
            &p,
            "bad_episodes = [\"ep3\"]\n[default]\naction = \"action\"\nstate = [0, 7]\n[default.cameras]\nfront = \"front\"\n[instructions]\nclick_mouse = \"click it\"\n",
        )
        .unwrap();
        let s = Selection::load(&p).unwrap();
        assert!(s.skip_static_frames && s.bad_episodes.contains("ep3"));
        assert_eq!(s.default.action, ActionSource::Action);
        assert_eq!(s.instruction("click_mouse", "x"), "click it");
        let y = dir.path().join("sel.yaml");
        fs_err::write(
            &y,
            "skip_static_frames: false\ndefault:\n  state: [null, 23]\n",
        )
        .unwrap();
        let s = Selection::load(&y).unwrap();
        assert!(!s.skip_static_frames);
        assert_eq!(s.default.state, Some(ColumnSlice(None, Some(23))));
        fs_err::write(&y, "defaults: {}\n").unwrap();
        let e = Selection::load(&y).unwrap_err().to_string();
        assert!(e.contains("sel.yaml") && e.contains("defaults"), "{e}");
    }

    #[test]
    fn prompt_variants_from_the_spec_or_an_instructions_file() {
        let spec = dexjoco_core::TaskSpec::builtin("hammer_nail").unwrap();
        let mut sel = Selection::default();
        let aug = sel.task_aug("hammer_nail", &spec.prompt);
        assert_eq!(aug[0], spec.prompt, "the instruction first");
        assert_eq!(aug[1..], spec.prompt_variants[..]);
        assert_eq!(sel.most_task_aug(), 1 + spec.prompt_variants.len());
        let dir = tempfile::tempdir().unwrap();
        let y = dir.path().join("variants.yaml");
        fs_err::write(
            &y,
            "hammer_nail: [\"hit the nail\", \"hit the nail\", \"\"]\nmy_task: do it\n",
        )
        .unwrap();
        sel.load_prompt_variants(&y).unwrap();
        assert_eq!(
            sel.task_aug("hammer_nail", "drive it"),
            ["drive it", "hit the nail"],
            "each once, empty texts dropped"
        );
        assert_eq!(sel.task_aug("my_task", "my_task"), ["my_task", "do it"]);
        fs_err::write(&y, "hammer_nail: {a: 1}\n").unwrap();
        let e = sel.load_prompt_variants(&y).unwrap_err().to_string();
        assert!(e.contains("variants.yaml"), "{e}");
    }
}
