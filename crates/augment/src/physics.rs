//! The physics of a replay: the episode restored from its recorded `state[0]`, every
//! recorded action stepped with the DexJoCo controller; success and the deviation from
//! the recorded states.

use dexjoco_core::{Episode, FrameArray};
use dexjoco_sim::{EnvOptions, TaskEnv};

use crate::config::AugmentConfig;
use crate::error::{AugmentError, sim_err};
use crate::inputs::Source;
use crate::run::TaskAssets;

/// The physics-only replay of one episode.
pub(crate) struct Physics {
    pub(crate) states: FrameArray,
    pub(crate) first_success: Option<usize>,
    pub(crate) deviation: f64,
    pub(crate) deviation_at: Option<(usize, usize)>,
}

pub(crate) fn frames(src: &Source, config: &AugmentConfig) -> usize {
    let n = src.episode.len();
    config.max_frames.map_or(n, |m| m.min(n))
}

pub(crate) fn new_env(src: &Source, assets: &TaskAssets) -> Result<TaskEnv, AugmentError> {
    let state0 = src
        .episode
        .array(Episode::STATE)
        .expect("checked")
        .row(0)
        .to_vec();
    TaskEnv::from_initial_state(&assets.scene, &src.spec, &state0, EnvOptions::default())
        .map_err(sim_err(&src.episode.id))
}

pub(crate) fn simulate(
    src: &Source,
    assets: &TaskAssets,
    n: usize,
) -> Result<Physics, AugmentError> {
    let mut env = new_env(src, assets)?;
    let actions = src.episode.array(Episode::ACTION).expect("checked");
    let recorded = src.episode.array(Episode::STATE).expect("checked");
    let mut rows = Vec::with_capacity(n);
    let mut first_success = None;
    for k in 0..n {
        rows.push(env.state());
        let v = env.step(actions.row(k)).map_err(sim_err(&src.episode.id))?;
        if v.success && first_success.is_none() {
            first_success = Some(k);
        }
    }
    let states = FrameArray::from_rows(&rows).map_err(|e| AugmentError::Input(e.to_string()))?;
    let (deviation, deviation_at) = deviation(&states, recorded);
    Ok(Physics {
        states,
        first_success,
        deviation,
        deviation_at,
    })
}

/// Largest absolute difference and where; a width mismatch or a NaN counts as infinite.
pub(crate) fn deviation(
    replayed: &FrameArray,
    recorded: &FrameArray,
) -> (f64, Option<(usize, usize)>) {
    if replayed.width() != recorded.width() {
        return (f64::INFINITY, None);
    }
    let mut best = (0.0, None);
    for k in 0..replayed.len().min(recorded.len()) {
        for (c, (a, b)) in replayed.row(k).iter().zip(recorded.row(k)).enumerate() {
            let d = (a - b).abs();
            let d = if d.is_nan() { f64::INFINITY } else { d };
            if d > best.0 {
                best = (d, Some((k, c)));
            }
        }
    }
    best
}
