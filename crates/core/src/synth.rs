//! Synthetic, valid episodes for tests and benchmarks: smooth motions with unit
//! quaternions, hand targets inside their ranges and the task's privileged layout.

use std::collections::BTreeMap;

use crate::episode::{Episode, FrameArray};
use crate::layout::{DEXJOCO_FPS, HAND_CTRL_RANGES, HAND_DOF, POSE_DIM};
use crate::task_spec::{PrivilegedKind, TaskSpec};

/// A unit quaternion that varies with `a` and `b`.
fn unit_quat(a: f64, b: f64) -> [f64; 4] {
    crate::pose::normalize([a.cos(), 0.3 * b.sin(), 0.2 * a.sin(), 0.1 * b.cos()])
}

/// A valid episode of `task` with `frames` frames; `seed` varies the values.
pub fn episode(task: &TaskSpec, frames: usize, seed: u64) -> Episode {
    let setup = task.setup;
    let s = seed as f64 * 0.7311;
    let per_arm = POSE_DIM + HAND_DOF;
    let mut action = FrameArray::zeros(frames, setup.action_dim());
    let mut state = FrameArray::zeros(frames, task.state.width);
    let dh = 0.05 * ((s * 3.1).sin() * 0.5 + 0.5);
    for k in 0..frames {
        let t = k as f64 / DEXJOCO_FPS + s;
        let row = action.row_mut(k);
        for arm in 0..setup.arms() {
            let a = &mut row[arm * per_arm..(arm + 1) * per_arm];
            a[0] = -0.3 + 0.1 * (t * 0.5).sin();
            a[1] = 0.1 * (t * 0.3).cos() + if arm == 1 { 0.4 } else { 0.0 };
            a[2] = 1.1 + 0.05 * (t * 0.7).sin();
            a[3..7].copy_from_slice(&unit_quat(0.2 * t, 0.1 * t + arm as f64));
            for (j, v) in a[7..].iter_mut().enumerate() {
                let (lo, hi) = HAND_CTRL_RANGES[j];
                *v = lo + (hi - lo) * (0.5 + 0.4 * (t * 0.9 + j as f64).sin());
            }
        }
        let srow = state.row_mut(k);
        for arm in 0..setup.arms() {
            let p = &mut srow[arm * POSE_DIM..(arm + 1) * POSE_DIM];
            p[0] = -0.3 + 0.1 * (t * 0.5 - 0.05).sin();
            p[1] = 0.1 * (t * 0.3).cos();
            p[2] = 1.1;
            p[3..7].copy_from_slice(&unit_quat(0.2 * t - 0.01, 0.1 * t));
        }
        let hands = setup.arms() * POSE_DIM;
        for j in 0..setup.arms() * HAND_DOF {
            srow[hands + j] = 0.3 * (t + j as f64).sin();
        }
        for f in task.privileged() {
            let v = &mut srow[f.start..f.start + f.kind.width()];
            match f.kind {
                PrivilegedKind::Pose => {
                    v[0] = -0.3 + 0.01 * s.sin();
                    v[1] = if f.object == "food" { 0.17 } else { -0.22 };
                    v[2] = 0.95 + dh;
                    v[3..7].copy_from_slice(&unit_quat(s, 0.0));
                }
                PrivilegedKind::Position => {
                    v.copy_from_slice(&[-0.22, 0.0, 0.92 + dh]);
                }
                PrivilegedKind::TableOffset => v[0] = dh,
            }
        }
    }
    let mut arrays = BTreeMap::new();
    arrays.insert(Episode::ACTION.to_owned(), action);
    arrays.insert(Episode::STATE.to_owned(), state);
    arrays.insert(
        Episode::TIMESTAMP.to_owned(),
        Episode::regular_timestamps(frames, DEXJOCO_FPS),
    );
    let mut ep = Episode {
        id: format!("synth-{seed}"),
        task: task.id.clone(),
        prompt: task.prompt.clone(),
        fps: DEXJOCO_FPS,
        arrays,
        cameras: Vec::new(),
    };
    ep.compute_action_rotvec(setup)
        .expect("action has the setup's width");
    ep
}
