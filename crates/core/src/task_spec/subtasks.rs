//! A task's subtasks: the steps a person would name ("grasp the hammer", "drive the
//! nail"), each belonging to an arm's lane (or both), about one object (the frame in which
//! the hand moves during it), and ending when a node of the condition graph first holds
//! after the subtasks it waits for have ended.
//!
//! Order: within a lane, list order (a `both` subtask is in both lanes, so it waits for
//! each arm's previous subtask and each arm's next one waits for it); across lanes,
//! subtasks run in parallel unless `after` names a subtask of the other arm to wait for.

use std::collections::BTreeSet;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::{ArmSetup, Node, TaskSpec, TaskSpecError};

/// Whose subtask it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SubtaskArm {
    /// The one arm of a single-arm task.
    Single,
    /// The left arm of a bimanual task.
    Left,
    /// The right arm of a bimanual task.
    Right,
    /// Both arms together (one object moved by both hands, in one frame).
    Both,
}

impl SubtaskArm {
    /// The lanes (arm indices in the state's order: right 0, left 1; the single arm 0)
    /// this subtask occupies.
    pub fn lanes(self) -> &'static [usize] {
        match self {
            Self::Single | Self::Right => &[0],
            Self::Left => &[1],
            Self::Both => &[0, 1],
        }
    }

    /// Lower-case name, as in the spec.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Single => "single",
            Self::Left => "left",
            Self::Right => "right",
            Self::Both => "both",
        }
    }
}

/// When one subtask ran in a rollout (a replay, a scripted plan, an eval episode):
/// frames `start` to `end` (the frame before action `k` is frame `k`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
pub struct SubtaskSpan {
    /// The subtask's id.
    pub id: String,
    /// Its text (from the task spec the rollout ran under).
    #[serde(default)]
    pub text: String,
    /// The first frame of it: the frame after the last of the subtasks it waits for
    /// ended (0 for one that waits for none); `None` when those never all ended.
    #[serde(default)]
    pub start: Option<usize>,
    /// The step on which it ended (0-based: the state after action `end` satisfied its
    /// end node; frame `end` is its last), or `None` when it never did.
    pub end: Option<usize>,
}

impl SubtaskSpan {
    /// Whether it ended.
    pub fn completed(&self) -> bool {
        self.end.is_some()
    }
}

/// One subtask of a task.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Subtask {
    /// Id (snake_case), e.g. `grasp_hammer`.
    pub id: String,
    /// What a person would say, e.g. "grasp the hammer" (the LeRobot subtask text).
    pub text: String,
    /// Whose it is: `single` in a one-arm task; `left`, `right` or `both` in a two-arm one.
    pub arm: SubtaskArm,
    /// The object it is about (a state object): the frame the hand moves in during it.
    pub object: String,
    /// The node that ends it: the first step on which it holds, once every subtask this
    /// one waits for has ended.
    pub end: String,
    /// Subtasks of the other arm this one waits for (besides its own lane's previous
    /// one), by id; each must come earlier in the list.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub after: Vec<String>,
}

impl TaskSpec {
    /// For each subtask, the indices of the subtasks it waits for: the previous one in
    /// each of its lanes, and those its `after` names.
    pub fn subtask_predecessors(&self) -> Vec<Vec<usize>> {
        let mut last_in_lane: [Option<usize>; 2] = [None, None];
        self.subtasks
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let mut before: BTreeSet<usize> = s
                    .arm
                    .lanes()
                    .iter()
                    .filter_map(|&l| last_in_lane[l])
                    .collect();
                before.extend(
                    s.after
                        .iter()
                        .filter_map(|a| self.subtasks.iter().position(|o| &o.id == a)),
                );
                for &l in s.arm.lanes() {
                    last_in_lane[l] = Some(i);
                }
                before.into_iter().collect()
            })
            .collect()
    }

    /// The subtasks' checks: unique safe ids, texts, arms that fit the setup, known
    /// objects, end nodes that exist and read no hand of another arm, `after` naming
    /// earlier subtasks of another arm.
    pub(super) fn validate_subtasks(&self) -> Result<(), TaskSpecError> {
        let objects: BTreeSet<&str> = self.state.objects.iter().map(|o| o.name.as_str()).collect();
        let mut seen = BTreeSet::new();
        for (i, s) in self.subtasks.iter().enumerate() {
            let field = |f: &str| format!("subtasks[{i}].{f}");
            crate::safe_name("subtask id", &s.id)
                .map_err(|e| self.invalid(&field("id"), e.to_string()))?;
            if !seen.insert(s.id.as_str()) {
                return Err(self.invalid(&field("id"), format!("'{}' is given twice", s.id)));
            }
            if s.text.trim().is_empty() {
                return Err(self.invalid(&field("text"), "must not be empty".into()));
            }
            let fits = match self.setup {
                ArmSetup::SingleArm => s.arm == SubtaskArm::Single,
                ArmSetup::Bimanual => s.arm != SubtaskArm::Single,
            };
            if !fits {
                return Err(self.invalid(
                    &field("arm"),
                    format!(
                        "'{}' in a {} task (use {})",
                        s.arm.as_str(),
                        match self.setup {
                            ArmSetup::SingleArm => "one-arm",
                            ArmSetup::Bimanual => "two-arm",
                        },
                        match self.setup {
                            ArmSetup::SingleArm => "single",
                            ArmSetup::Bimanual => "left, right or both",
                        }
                    ),
                ));
            }
            if !objects.contains(s.object.as_str()) {
                return Err(self.invalid(
                    &field("object"),
                    format!(
                        "unknown object '{}' (the state's objects: {})",
                        s.object,
                        objects.iter().copied().collect::<Vec<_>>().join(", ")
                    ),
                ));
            }
            self.check_subtask_end(&field("end"), s)?;
            for a in &s.after {
                match self.subtasks[..i].iter().find(|o| &o.id == a) {
                    Some(o) if o.arm.lanes().iter().any(|l| s.arm.lanes().contains(l)) => {
                        return Err(self.invalid(
                            &field("after"),
                            format!("'{a}' is of the same arm: its lane orders it already"),
                        ));
                    }
                    Some(_) => {}
                    None => {
                        return Err(self
                            .invalid(&field("after"), format!("'{a}' is not an earlier subtask")));
                    }
                }
            }
        }
        Ok(())
    }

    /// A subtask's end is a node (not an output) whose inputs read no hand of another arm.
    fn check_subtask_end(&self, field: &str, s: &Subtask) -> Result<(), TaskSpecError> {
        if s.end.contains('.') || !self.nodes.contains_key(&s.end) {
            return Err(self.invalid(field, format!("'{}' is not a node of this task", s.end)));
        }
        let mut stack = vec![s.end.as_str()];
        let mut seen = BTreeSet::new();
        while let Some(name) = stack.pop() {
            if !seen.insert(name) {
                continue;
            }
            let Some(node) = self.nodes.get(name) else {
                continue;
            };
            if let Node::Grasp { hand, .. } = node
                && s.arm != SubtaskArm::Both
                && hand.arm() != s.arm
            {
                return Err(self.invalid(
                    field,
                    format!(
                        "node '{}' of subtask '{}' ({} arm) reads the {} hand through node '{name}'",
                        s.end,
                        s.id,
                        s.arm.as_str(),
                        hand.arm().as_str()
                    ),
                ));
            }
            stack.extend(
                node.inputs()
                    .into_iter()
                    .map(|i| i.split('.').next().unwrap_or(i)),
            );
        }
        Ok(())
    }
}
