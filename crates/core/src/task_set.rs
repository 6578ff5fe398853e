//! The set of known tasks: the specs shipped in `schemas/tasks/` (embedded, parsed once
//! per process), optionally with a folder of specs that replace or add tasks. Every fact
//! a stage needs about a task (setup, state layout, step cap, prompt, cameras, display
//! name, table order) is read from its [`TaskSpec`]; nothing restates them.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;

use crate::layout::POSE_DIM;
use crate::task_spec::{TaskSpec, TaskSpecError};

/// The task specs shipped in `schemas/tasks/`, embedded at build time: (task id, TOML).
pub const BUILTIN_SPEC_FILES: [(&str, &str); 11] = {
    macro_rules! specs {
        ($($id:literal),*) => {
            [$(($id, include_str!(concat!("../../../schemas/tasks/", $id, ".toml")))),*]
        };
    }
    specs!(
        "bimanual_assembly",
        "bimanual_hanoi",
        "bimanual_microwave_cook",
        "bimanual_photograph",
        "bimanual_unlock_ipad",
        "click_mouse",
        "fold_glasses",
        "hammer_nail",
        "pick_bucket",
        "pinch_tongs",
        "water_plant"
    )
};

/// Known tasks by id.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TaskSet {
    specs: BTreeMap<String, TaskSpec>,
}

impl TaskSet {
    /// The shipped specs, parsed on first use. An embedded spec is checked by this crate's
    /// tests, so failing to parse one is a build defect (a panic names it).
    pub fn builtin() -> &'static Self {
        static BUILTIN: OnceLock<TaskSet> = OnceLock::new();
        BUILTIN.get_or_init(|| Self {
            specs: BUILTIN_SPEC_FILES
                .iter()
                .map(|(id, text)| {
                    let spec = TaskSpec::from_toml_str(text, &format!("schemas/tasks/{id}.toml"))
                        .unwrap_or_else(|e| panic!("embedded task spec {id}: {e}"));
                    ((*id).to_owned(), spec)
                })
                .collect(),
        })
    }

    /// The shipped specs with those of `dir` (when given) replacing the shipped ones of
    /// the same id or adding tasks.
    pub fn with_dir(dir: Option<&Path>) -> Result<Self, TaskSpecError> {
        let mut set = Self::builtin().clone();
        if let Some(dir) = dir {
            for s in TaskSpec::load_dir(dir)? {
                set.specs.insert(s.id.clone(), s);
            }
        }
        Ok(set)
    }

    /// The spec of a task.
    pub fn get(&self, id: &str) -> Option<&TaskSpec> {
        self.specs.get(id)
    }

    /// Whether the task is known.
    pub fn contains(&self, id: &str) -> bool {
        self.specs.contains_key(id)
    }

    /// Every spec, sorted by task id.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = &TaskSpec> {
        self.specs.values()
    }

    /// Every task id, sorted.
    pub fn ids(&self) -> Vec<&str> {
        self.specs.keys().map(String::as_str).collect()
    }

    /// Number of tasks.
    pub fn len(&self) -> usize {
        self.specs.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.specs.is_empty()
    }
}

/// What a run of privileged state columns holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PrivilegedKind {
    /// An object's reset-time pose: position xyz + quaternion wxyz (7 values).
    Pose,
    /// A position only: xyz (3 values).
    Position,
    /// The table height offset dh (1 value).
    TableOffset,
}

impl PrivilegedKind {
    /// Number of columns.
    pub fn width(self) -> usize {
        match self {
            Self::Pose => POSE_DIM,
            Self::Position => 3,
            Self::TableOffset => 1,
        }
    }
}

/// One named run of privileged state columns of a task (after the proprioception).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PrivilegedField {
    /// Name in the state layout, e.g. `mouse.pose` or `dh`.
    pub name: String,
    /// The state object it belongs to (`mouse`), or `dh`.
    pub object: String,
    /// What it holds.
    pub kind: PrivilegedKind,
    /// First column in `state`.
    pub start: usize,
}

impl TaskSpec {
    /// The privileged part of `state` in column order: each state object's pose (or
    /// position), then the table offset `dh`. Names follow [`TaskSpec::state_layout`].
    pub fn privileged(&self) -> Vec<PrivilegedField> {
        let layout = self.state_layout();
        let mut out: Vec<PrivilegedField> = self
            .state
            .objects
            .iter()
            .map(|o| {
                let name = format!("{}.pose", o.name);
                PrivilegedField {
                    start: layout
                        .get(&name)
                        .expect("the layout names every object")
                        .start,
                    name,
                    object: o.name.clone(),
                    kind: if o.source.width() == POSE_DIM {
                        PrivilegedKind::Pose
                    } else {
                        PrivilegedKind::Position
                    },
                }
            })
            .collect();
        out.push(PrivilegedField {
            name: "dh".into(),
            object: "dh".into(),
            kind: PrivilegedKind::TableOffset,
            start: self.dh_column(),
        });
        out
    }

    /// Column of the table height offset dh in `state` (the last one).
    pub fn dh_column(&self) -> usize {
        self.state.width - 1
    }

    /// The raw keys of the task's camera streams (`front`, `ego`, `wrist_left`...).
    pub fn camera_keys(&self) -> impl Iterator<Item = &str> {
        self.cameras.iter().map(|c| c.key.as_str())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_set_is_parsed_once_and_complete() {
        let a = TaskSet::builtin();
        assert!(std::ptr::eq(a, TaskSet::builtin()));
        assert_eq!(a.len(), 11);
        assert_eq!(a.get("bimanual_hanoi").unwrap().state.width, 50);
        assert!(a.get("nope").is_none());
    }

    #[test]
    fn privileged_fields_cover_the_state_after_proprioception() {
        for t in TaskSet::builtin().iter() {
            let p = t.privileged();
            assert_eq!(p.first().unwrap().start, t.setup.proprio_dim(), "{}", t.id);
            assert_eq!(p.last().unwrap().start, t.dh_column());
            assert_eq!(t.state_layout().column_name(t.dh_column()), "dh[0]");
        }
        let hanoi = TaskSpec::builtin("bimanual_hanoi").unwrap();
        assert_eq!(hanoi.privileged()[0].kind, PrivilegedKind::Position);
    }
}
