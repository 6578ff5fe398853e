//! Where things are in a task environment now: a state object's world pose and each
//! arm's target.

use dexjoco_core::{NameKind, Pose, PoseSource};

use super::TaskEnv;
use crate::checker::name_id;

impl TaskEnv {
    /// The world pose now of the state object `name`: the body its pose source names
    /// (a free joint's body, a static or mocap body), or the geom for a geom's pose;
    /// `None` when the task has no state object of that name.
    pub fn object_pose(&self, name: &str) -> Option<Pose> {
        let object = self.spec.state.objects.iter().find(|o| o.name == name)?;
        let m = self.data.model();
        let (pos, mat) = match &object.source {
            PoseSource::FreeJoint(j) => {
                let b = m.jnt_bodyid()[name_id(m, NameKind::Joint, j)?] as usize;
                (self.data.xpos()[b], self.data.xmat()[b])
            }
            PoseSource::Body(n) | PoseSource::BodyPosition(n) | PoseSource::Mocap(n) => {
                let b = name_id(m, NameKind::Body, n)?;
                (self.data.xpos()[b], self.data.xmat()[b])
            }
            PoseSource::GeomLocal(n) => {
                let g = name_id(m, NameKind::Geom, n)?;
                (self.data.geom_xpos()[g], self.data.geom_xmat()[g])
            }
        };
        Some(Pose::new(pos, crate::control::mat_to_quat(&mat)))
    }

    /// The current arm targets (mocap pose) per arm: position and quaternion wxyz.
    pub fn targets(&self) -> Vec<([f64; 3], [f64; 4])> {
        self.robot
            .arms
            .iter()
            .map(|a| {
                (
                    self.data.mocap_pos()[a.mocap],
                    self.data.mocap_quat()[a.mocap],
                )
            })
            .collect()
    }
}
