//! The privileged part of a task's state, column by column: each state object's pose (or
//! position), then the table offset `dh`.

use super::TaskSpec;
use crate::layout::POSE_DIM;

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

    /// The columns of the privileged part of `state` (`mouse.pose[0]` ... `dh[0]`), in
    /// their order.
    pub fn privileged_names(&self) -> Vec<String> {
        let layout = self.state_layout();
        (self.setup.proprio_dim()..layout.width())
            .map(|c| layout.column_name(c))
            .collect()
    }

    /// The poses the environment state holds, in order: each state object's, then each
    /// pose the reset derives from them that is not itself a state object (a mouse pad
    /// placed from the mouse, Hanoi's disks from their base): named after the object, or
    /// after the body, joint or geom for a derived one.
    pub fn environment_poses(&self) -> Vec<(&str, &super::PoseSource)> {
        let objects = &self.state.objects;
        let mut out: Vec<(&str, &super::PoseSource)> = objects
            .iter()
            .map(|o| (o.name.as_str(), &o.source))
            .collect();
        for d in &self.state.derived {
            if !objects.iter().any(|o| o.source == d.target) {
                out.push((d.target.name(), &d.target));
            }
        }
        out
    }

    /// The columns of the environment state ([`crate::Episode::ENVIRONMENT_STATE`]): the
    /// [`Self::environment_poses`] now (`mouse.pose[0]` ... `mousepad.pose[6]`), then the
    /// table offset `dh[0]`.
    pub fn environment_state_names(&self) -> Vec<String> {
        let mut names: Vec<String> = self
            .environment_poses()
            .into_iter()
            .flat_map(|(name, source)| {
                (0..source.width()).map(move |i| format!("{name}.pose[{i}]"))
            })
            .collect();
        names.push("dh[0]".into());
        names
    }

    /// Column of the table height offset dh in `state` (the last one).
    pub fn dh_column(&self) -> usize {
        self.state.width - 1
    }
}
