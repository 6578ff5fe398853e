//! The set of known tasks: the specs shipped in `schemas/tasks/` (embedded, parsed once
//! per process), optionally with a folder of specs that replace or add tasks. Every fact
//! a stage needs about a task (setup, state layout, step cap, prompt, cameras, display
//! name, table order) is read from its [`TaskSpec`]; nothing restates them.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::OnceLock;

use crate::task_spec::{TaskSpec, TaskSpecError, builtin_specs};

/// Known tasks by id.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TaskSet {
    specs: BTreeMap<String, TaskSpec>,
}

impl TaskSet {
    /// The shipped specs, parsed on first use (see [`TaskSpec::builtin`]).
    pub fn builtin() -> &'static Self {
        static BUILTIN: OnceLock<TaskSet> = OnceLock::new();
        BUILTIN.get_or_init(|| Self {
            specs: builtin_specs().clone(),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::task_spec::BUILTIN_SPEC_FILES;

    #[test]
    fn builtin_set_is_parsed_once_and_complete() {
        let a = TaskSet::builtin();
        assert!(std::ptr::eq(a, TaskSet::builtin()));
        assert_eq!(a.len(), 11);
        assert_eq!(a.get("bimanual_hanoi").unwrap().state.width, 50);
        assert!(a.get("nope").is_none());
    }

    #[test]
    fn the_embedded_specs_are_the_folder() {
        let tasks_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../schemas/tasks");
        let from_dir = TaskSpec::load_dir(&tasks_dir).unwrap();
        let embedded: Vec<TaskSpec> = TaskSet::builtin().iter().cloned().collect();
        assert_eq!(embedded, from_dir);
        assert_eq!(TaskSpec::builtin("click_mouse").unwrap(), &from_dir[5]);
        assert!(TaskSpec::builtin("no_such_task").is_none());
        // A folder of specs replaces built-in ones by id and adds new ones.
        let tmp = tempfile::tempdir().unwrap();
        let mut text = BUILTIN_SPEC_FILES[5]
            .1
            .replace("prompt = \"", "prompt = \"Changed. ");
        fs_err::write(tmp.path().join("click_mouse.toml"), &text).unwrap();
        text = text.replace("id = \"click_mouse\"", "id = \"my_click\"");
        fs_err::write(tmp.path().join("my_click.toml"), &text).unwrap();
        let all: Vec<TaskSpec> = TaskSet::with_dir(Some(tmp.path()))
            .unwrap()
            .iter()
            .cloned()
            .collect();
        assert_eq!(all.len(), 12);
        let mine = all.iter().find(|s| s.id == "click_mouse").unwrap();
        assert!(mine.prompt.starts_with("Changed. "), "{}", mine.prompt);
        assert!(all.iter().any(|s| s.id == "my_click"));
        let builtin: Vec<TaskSpec> = TaskSet::with_dir(None).unwrap().iter().cloned().collect();
        assert_eq!(builtin, from_dir);
    }
}
