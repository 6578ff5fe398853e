//! Task specifications as data: `schemas/tasks/<task_id>.toml`.
//!
//! A [`TaskSpec`] says everything a simulator needs to know about one DexJoCo task
//! besides the scene file itself: the robot setup, prompt and cameras, the layout of
//! the privileged part of the state and how to restore it, the randomization ranges,
//! the step cap, and the success and failure conditions.
//!
//! Conditions are a graph of named [`Node`]s, each one reusable primitive of one of the
//! four constraint kinds of the DexJoCo paper (g_pose, g_joint, g_contact, g_seq) or a
//! named scene mechanic (the nail that sinks, the iPad keypad, the Hanoi stacks). A node
//! refers to other nodes by name (`"on_pad"`) or to a named output of a node
//! (`"nail.depth"`); the simulator evaluates them in dependency order after every step.
//!
//! The files are read strictly (unknown keys are errors) and then checked by
//! [`TaskSpec::validate`]; the JSON Schema `schemas/task-spec.schema.json` is generated
//! from these types, so schema and reader cannot disagree.
//!
//! The module is split by job: this file holds the spec itself and its loading;
//! `builtin` the specs shipped in `schemas/tasks/`; `state` the reset, table, privileged
//! state and randomization types; `privileged` the privileged state's columns; `nodes`
//! the condition graph's node types; `check` the validation, evaluation order and the
//! scene names a spec uses.

mod builtin;
mod check;
mod nodes;
mod privileged;
mod state;
mod subtasks;
#[cfg(test)]
mod tests;

use std::collections::BTreeMap;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::layout::{ArmSetup, ArrayLayout};

pub use builtin::BUILTIN_SPEC_FILES;
pub(crate) use builtin::builtin_specs;
pub use check::NameKind;
pub use nodes::*;
pub use privileged::{PrivilegedField, PrivilegedKind};
pub use state::*;
pub use subtasks::{Subtask, SubtaskArm, SubtaskSpan};

/// One DexJoCo task.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TaskSpec {
    /// Task id, e.g. `click_mouse` (the file is `<id>.toml`).
    pub id: String,
    /// Name in the paper, e.g. `Click Mouse`.
    pub name: String,
    /// Place of the task in the paper's tables (1 = first column); tasks without one
    /// come after, by id.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub paper_order: Option<u32>,
    /// One arm or two.
    pub setup: ArmSetup,
    /// File name of the reference scene (in a scene pack such as DexJoCo's `xmls/`).
    pub scene: String,
    /// The language instruction.
    pub prompt: String,
    /// Other ways a person says the instruction (paraphrases of `prompt`): the `task_aug`
    /// rows `convert` gives each episode of the task in LeRobot v3.0's language columns.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub prompt_variants: Vec<String>,
    /// Episode length limit in control steps.
    pub step_cap: usize,
    /// Camera streams: raw key and scene camera.
    pub cameras: Vec<CameraSpec>,
    /// How the environment resets the robot.
    #[serde(default)]
    pub reset: ResetSpec,
    /// The table and its height offset `dh`.
    #[serde(default)]
    pub table: TableSpec,
    /// The privileged part of the state and how a recorded one is restored.
    pub state: StateSpec,
    /// Object placement randomization, in draw order.
    #[serde(default)]
    pub placement: Vec<Placement>,
    /// Dynamics randomization ("rand-dynamics"), in draw order.
    #[serde(default)]
    pub dynamics: Vec<DynamicsRandomization>,
    /// The condition graph: node name -> node.
    pub nodes: BTreeMap<String, Node>,
    /// The node whose value is the task's success.
    pub success: String,
    /// The node whose value ends the episode as a failure, if the task has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub failure: Option<String>,
    /// The steps a person would name, in order (per arm), each ending on a node.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub subtasks: Vec<Subtask>,
}

/// A camera stream of the task.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// Key of the stream in the raw data (`front`, `ego`, `wrist_left`...).
    pub key: String,
    /// Camera name in the scene.
    pub camera: String,
}

/// Errors of a task spec.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TaskSpecError {
    /// The TOML is malformed or does not match the types.
    #[error("task spec '{file}': {message}")]
    Parse {
        /// File or label.
        file: String,
        /// What is wrong.
        message: String,
    },
    /// The spec parses but is inconsistent.
    #[error("task spec {}'{task}': {message}", in_file(file))]
    Invalid {
        /// The file (or label), when known.
        file: String,
        /// Task id.
        task: String,
        /// What is wrong, starting with the field (`field 'nodes.on_pad'`).
        message: String,
    },
}

/// ` in 'FILE'` when the file is known.
fn in_file(file: &str) -> String {
    if file.is_empty() {
        String::new()
    } else {
        format!("'{file}', task ")
    }
}

/// The key path of the first NaN or infinite number in a TOML value.
fn non_finite(v: &toml::Value, path: &str) -> Option<String> {
    let join = |k: &str| {
        if path.is_empty() {
            k.to_owned()
        } else {
            format!("{path}.{k}")
        }
    };
    match v {
        toml::Value::Float(f) if !f.is_finite() => Some(path.to_owned()),
        toml::Value::Array(a) => a
            .iter()
            .enumerate()
            .find_map(|(i, x)| non_finite(x, &format!("{path}[{i}]"))),
        toml::Value::Table(t) => t.iter().find_map(|(k, x)| non_finite(x, &join(k))),
        _ => None,
    }
}

impl TaskSpecError {
    /// The same error, naming the file it is about.
    pub fn in_file(self, file: &str) -> Self {
        match self {
            Self::Invalid { task, message, .. } => Self::Invalid {
                file: file.into(),
                task,
                message,
            },
            other => other,
        }
    }
}

impl TaskSpec {
    /// Parses a spec from TOML text (strict: unknown keys are errors; every number
    /// finite) and validates it. Errors name `label` and the field.
    pub fn from_toml_str(text: &str, label: &str) -> Result<Self, TaskSpecError> {
        let parse = |message: String| TaskSpecError::Parse {
            file: label.into(),
            message,
        };
        let spec: Self = toml::from_str(text).map_err(|e| parse(e.to_string()))?;
        let table: toml::Table = toml::from_str(text).map_err(|e| parse(e.to_string()))?;
        if let Some(field) = non_finite(&toml::Value::Table(table), "") {
            return Err(parse(format!("field '{field}': numbers must be finite")));
        }
        spec.validate().map_err(|e| e.in_file(label))?;
        Ok(spec)
    }

    /// Reads and validates one spec file.
    pub fn from_file(path: &std::path::Path) -> Result<Self, TaskSpecError> {
        let text = fs_err::read_to_string(path).map_err(|e| TaskSpecError::Parse {
            file: path.display().to_string(),
            message: e.to_string(),
        })?;
        let spec = Self::from_toml_str(&text, &path.display().to_string())?;
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        if stem != spec.id {
            return Err(spec
                .invalid("id", "the file must be named after the task id".into())
                .in_file(&path.display().to_string()));
        }
        Ok(spec)
    }

    /// Reads every `*.toml` spec of a folder, sorted by task id.
    pub fn load_dir(dir: &std::path::Path) -> Result<Vec<Self>, TaskSpecError> {
        let entries = fs_err::read_dir(dir).map_err(|e| TaskSpecError::Parse {
            file: dir.display().to_string(),
            message: e.to_string(),
        })?;
        let mut paths: Vec<_> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        paths.sort();
        paths.iter().map(|p| Self::from_file(p)).collect()
    }

    /// The JSON Schema of the spec file (what `schemas/task-spec.schema.json` holds).
    pub fn json_schema() -> serde_json::Value {
        let schema = schemars::schema_for!(TaskSpec);
        serde_json::to_value(schema).expect("a schema is JSON")
    }

    /// The full state layout: proprioception, then the objects' poses, then `dh`.
    pub fn state_layout(&self) -> ArrayLayout {
        let mut l = self.setup.proprio_layout();
        for o in &self.state.objects {
            l.push(format!("{}.pose", o.name), o.source.width());
        }
        l.push("dh", 1);
        l
    }

    /// The raw keys of the task's camera streams (`front`, `ego`, `wrist_left`...).
    pub fn camera_keys(&self) -> impl Iterator<Item = &str> {
        self.cameras.iter().map(|c| c.key.as_str())
    }
}
