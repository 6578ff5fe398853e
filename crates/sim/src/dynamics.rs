//! Dynamics randomization (`augment --dynamics`, `eval --randomize-dynamics`, the paper's
//! "rand-dynamics"): per replay or episode,
//! the task spec's `[[dynamics]]` entries draw object masses, joint friction losses and
//! stiffnesses, always from the scene's original values (never compounding), and are
//! written into a copy of the model; the shared model is never edited.

use dexjoco_core::{DynamicsRandomization, NameKind, TaskSpec};
use mujoco_rs::prelude::MjModel;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::checker::name_id;
use crate::error::SimError;

/// One drawn dynamics value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DynamicsValue {
    /// `mass_scale`, `frictionloss_uniform`, `frictionloss_scale` or `stiffness_scale`.
    pub kind: String,
    /// The body (mass) or joint (friction loss, stiffness).
    pub target: String,
    /// The scene's value.
    pub original: f64,
    /// The value used by this replay.
    pub value: f64,
}

/// The seed of a replay's dynamics draw: its own stream, separate from the visual one, so
/// a replay looks the same with and without `--dynamics`.
pub fn dynamics_seed(replay_seed: u64) -> u64 {
    let mut h = Sha256::new();
    h.update(b"dexjoco-augment/dynamics/v1");
    h.update(replay_seed.to_le_bytes());
    let d = h.finalize();
    u64::from_le_bytes(d[..8].try_into().expect("8 bytes"))
}

/// Where a value lives in the model.
enum Slot {
    BodyMass(usize),
    DofFrictionloss(usize),
    JointStiffness(usize),
}

fn slot(
    model: &MjModel,
    spec: &TaskSpec,
    d: &DynamicsRandomization,
) -> Result<(Slot, String), SimError> {
    let missing = |kind: &str, name: &str| SimError::DynamicsName {
        task: spec.id.clone(),
        kind: kind.into(),
        name: name.into(),
    };
    let joint_dof = |j: &str| {
        name_id(model, NameKind::Joint, j)
            .map(|id| model.jnt_dofadr()[id] as usize)
            .ok_or_else(|| missing("joint", j))
    };
    Ok(match d {
        DynamicsRandomization::MassScale { body, .. } => (
            Slot::BodyMass(
                name_id(model, NameKind::Body, body).ok_or_else(|| missing("body", body))?,
            ),
            body.clone(),
        ),
        DynamicsRandomization::FrictionlossUniform { joint, .. }
        | DynamicsRandomization::FrictionlossScale { joint, .. } => {
            (Slot::DofFrictionloss(joint_dof(joint)?), joint.clone())
        }
        DynamicsRandomization::StiffnessScale { joint, .. } => (
            Slot::JointStiffness(
                name_id(model, NameKind::Joint, joint).ok_or_else(|| missing("joint", joint))?,
            ),
            joint.clone(),
        ),
    })
}

fn read(model: &MjModel, s: &Slot) -> f64 {
    match *s {
        Slot::BodyMass(b) => model.body_mass()[b],
        Slot::DofFrictionloss(d) => model.dof_frictionloss()[d],
        Slot::JointStiffness(j) => model.jnt_stiffness()[j],
    }
}

/// Draws the task's dynamics values for one replay, in the spec's order, from `model`'s
/// (original) values.
pub fn sample_dynamics(
    spec: &TaskSpec,
    model: &MjModel,
    seed: u64,
) -> Result<Vec<DynamicsValue>, SimError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::with_capacity(spec.dynamics.len());
    for d in &spec.dynamics {
        let (s, target) = slot(model, spec, d)?;
        let original = read(model, &s);
        let (kind, value) = match d {
            DynamicsRandomization::MassScale { range, .. } => (
                "mass_scale",
                original * rng.random_range(range[0]..=range[1]),
            ),
            DynamicsRandomization::FrictionlossUniform { range, .. } => (
                "frictionloss_uniform",
                rng.random_range(range[0]..=range[1]),
            ),
            DynamicsRandomization::FrictionlossScale { range, .. } => (
                "frictionloss_scale",
                original * rng.random_range(range[0]..=range[1]),
            ),
            DynamicsRandomization::StiffnessScale { range, .. } => (
                "stiffness_scale",
                original * rng.random_range(range[0]..=range[1]),
            ),
        };
        out.push(DynamicsValue {
            kind: kind.into(),
            target,
            original,
            value,
        });
    }
    Ok(out)
}

/// A copy of `model` with the drawn values written in (inertia kept, as the reference).
pub fn apply_dynamics(
    spec: &TaskSpec,
    model: &MjModel,
    values: &[DynamicsValue],
) -> Result<MjModel, SimError> {
    let mut m = model.clone();
    for (d, v) in spec.dynamics.iter().zip(values) {
        let (s, _) = slot(model, spec, d)?;
        match s {
            Slot::BodyMass(b) => m.body_mass_mut()[b] = v.value,
            Slot::DofFrictionloss(i) => m.dof_frictionloss_mut()[i] = v.value,
            Slot::JointStiffness(j) => m.jnt_stiffness_mut()[j] = v.value,
        }
    }
    Ok(m)
}

/// Reads the values `values` name back from a model (for checks).
pub fn read_dynamics(spec: &TaskSpec, model: &MjModel) -> Result<Vec<f64>, SimError> {
    spec.dynamics
        .iter()
        .map(|d| slot(model, spec, d).map(|(s, _)| read(model, &s)))
        .collect()
}
