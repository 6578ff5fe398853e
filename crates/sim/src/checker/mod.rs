//! Evaluates a task spec's condition graph on the simulation after every control step.
//!
//! [`SuccessChecker`] is the public face: `compile` turns a spec into nodes with their
//! resolved ids and state (all missing names listed at once); `eval` evaluates them after
//! each step, in dependency order.

mod compile;
mod eval;

use dexjoco_core::{NameKind, TaskSpec};
use mujoco_rs::prelude::{MjData, MjModel, MjtObjBase};
use mujoco_rs::wrappers::mj_model::traits::ModelType;

use crate::error::SimError;
use crate::primitives::{Count, Edge, Hanoi, Hold, Keypad, Sequence};

pub(crate) use compile::Resolver;
use compile::{Compiled, Port, output_names};
use eval::{read_joint, read_point};

/// The id of a named object of a model, or `None`.
pub fn name_id(model: &MjModel, kind: NameKind, name: &str) -> Option<usize> {
    let t = match kind {
        NameKind::Joint => MjtObjBase::mjOBJ_JOINT,
        NameKind::Body => MjtObjBase::mjOBJ_BODY,
        NameKind::Site => MjtObjBase::mjOBJ_SITE,
        NameKind::Geom => MjtObjBase::mjOBJ_GEOM,
        NameKind::Camera => MjtObjBase::mjOBJ_CAMERA,
        NameKind::Sensor => MjtObjBase::mjOBJ_SENSOR,
        NameKind::Actuator => MjtObjBase::mjOBJ_ACTUATOR,
    };
    model.name_to_id(t, name)
}

/// Every name a spec refers to that the model lacks, as `kind 'name'`.
pub fn unresolved_names(spec: &TaskSpec, model: &MjModel) -> Vec<String> {
    spec.scene_names()
        .into_iter()
        .filter(|(k, n)| name_id(model, *k, n).is_none())
        .map(|(k, n)| format!("{} '{n}'", k.as_str()))
        .collect()
}

/// What the checker says after a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Verdict {
    /// The task's success condition holds on this step.
    pub success: bool,
    /// The task's failure condition holds (the episode ends as a failure).
    pub failure: bool,
}

/// Evaluates a [`TaskSpec`]'s conditions on an `MjData` after every control step.
///
/// Call [`reset`](Self::reset) after the environment's reset or restore (it reads the
/// reset-time values: joint rest values, site heights, the nail height),
/// [`after_substep`](Self::after_substep) after each physics substep, and
/// [`after_step`](Self::after_step) after the substeps of a control step.
#[derive(Debug, Clone)]
pub struct SuccessChecker {
    names: Vec<String>,
    nodes: Vec<Compiled>,
    values: Vec<bool>,
    outputs: Vec<Vec<f64>>,
    success: Port,
    failure: Option<Port>,
}

impl SuccessChecker {
    /// The digits of keypad buttons newly pressed on the last step (the iPad task; empty
    /// otherwise), in button order, right or wrong: the reference's `pressed_digits`.
    pub fn keypad_presses(&self) -> Vec<u8> {
        self.nodes
            .iter()
            .flat_map(|n| match n {
                Compiled::Keypad { state, .. } => state.last.clone(),
                _ => Vec::new(),
            })
            .collect()
    }

    /// Compiles a spec for a model; every missing scene name is listed in the error.
    pub fn new(spec: &TaskSpec, model: &MjModel) -> Result<Self, SimError> {
        let g = compile::compile(spec, model)?;
        let n = g.nodes.len();
        Ok(Self {
            outputs: g
                .names
                .iter()
                .map(|name| vec![0.0; spec.nodes[name].outputs().len()])
                .collect(),
            names: g.names,
            nodes: g.nodes,
            values: vec![false; n],
            success: g.success,
            failure: g.failure,
        })
    }

    /// Node names in evaluation order.
    pub fn node_names(&self) -> &[String] {
        &self.names
    }

    /// A node's value on the last step.
    pub fn value(&self, node: &str) -> Option<bool> {
        self.names
            .iter()
            .position(|n| n == node)
            .map(|i| self.values[i])
    }

    /// A node's named output on the last step (booleans as 0 / 1).
    pub fn output(&self, node: &str, output: &str) -> Option<f64> {
        let i = self.names.iter().position(|n| n == node)?;
        let names = output_names(&self.nodes[i]);
        let k = names.iter().position(|o| *o == output)?;
        Some(self.outputs[i][k])
    }

    /// Reads the reset-time values and clears every counter and latch.
    pub fn reset<M: ModelType>(&mut self, data: &MjData<M>) {
        for (i, node) in self.nodes.iter_mut().enumerate() {
            self.values[i] = false;
            self.outputs[i].iter_mut().for_each(|v| *v = 0.0);
            match node {
                Compiled::Rise { sites, z0, .. } => {
                    for (z, s) in z0.iter_mut().zip(sites.iter()) {
                        *z = data.site_xpos()[*s][2];
                    }
                }
                Compiled::Above {
                    reference, ref_z, ..
                } => *ref_z = read_point(data, *reference)[2],
                Compiled::JointRise {
                    joint, at_reset, ..
                } => *at_reset = read_joint(data, *joint),
                Compiled::JointLatch { initial, state, .. } => *state = *initial,
                Compiled::Held { hold, .. } => *hold = Hold::default(),
                Compiled::Rising { edge, .. } | Compiled::Falling { edge, .. } => {
                    *edge = Edge::default()
                }
                Compiled::Counter { count, .. } => *count = Count::default(),
                Compiled::Latch { state, .. } => *state = false,
                Compiled::Seq { seq, .. } => *seq = Sequence::default(),
                Compiled::Nail {
                    face,
                    mocap,
                    state,
                    z0,
                    ..
                } => {
                    state.reset(data.geom_xpos()[*face][2]);
                    *z0 = data.mocap_pos()[*mocap][2];
                }
                Compiled::Keypad { state, .. } => *state = Keypad::default(),
                Compiled::Hanoi { state, .. } => *state = Hanoi::default(),
                _ => {}
            }
        }
    }

    /// Bookkeeping after each physics substep (the nail's face speed window).
    pub fn after_substep<M: ModelType>(&mut self, data: &MjData<M>) {
        for node in &mut self.nodes {
            if let Compiled::Nail {
                face,
                params,
                state,
                ..
            } = node
            {
                state.sample(data.geom_xpos()[*face][2], params);
            }
        }
    }

    /// After the substeps of a control step: runs the scene mechanics (which may move
    /// a mocap body and call `mj_forward`, as the reference does), then evaluates every
    /// node in dependency order.
    pub fn after_step<M: ModelType>(&mut self, data: &mut MjData<M>) -> Verdict {
        for i in 0..self.nodes.len() {
            let (value, outs) = self.eval(i, data);
            self.values[i] = value;
            for (k, v) in outs.into_iter().enumerate() {
                self.outputs[i][k] = v;
            }
        }
        Verdict {
            success: self.read(self.success),
            failure: self.failure.is_some_and(|f| self.read(f)),
        }
    }

    fn read(&self, p: Port) -> bool {
        match p.output {
            None => self.values[p.node],
            Some(k) => self.outputs[p.node][k] != 0.0,
        }
    }

    fn num(&self, p: Port) -> f64 {
        match p.output {
            None => f64::from(u8::from(self.values[p.node])),
            Some(k) => self.outputs[p.node][k],
        }
    }
}
