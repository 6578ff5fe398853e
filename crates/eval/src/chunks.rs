//! The reference client's action-chunk semantics (`eval_dexjoco_openpi.py`'s
//! `receive_actions`): a buffer of actions stamped with the control step they are for.
//! A chunk answers the observation of step `t`: its row `i` is for step `t + i`. When it
//! is merged at step `now`, actions of the buffer older than `now` are dropped, the
//! chunk's rows before `now` are dropped too, rows for steps the buffer already holds are
//! blended into them (weight `(k + 1) / (overlap + 1)` for the `k`-th overlapping step:
//! linear for positions and hands, geodesic for rotation vectors), and the rest are
//! appended. Actions are in the policy's layout: per arm `[xyz, rotvec, hand16]`.

use std::collections::VecDeque;

use dexjoco_core::{
    ArmSetup, HAND_DOF, ROTVEC_POSE_DIM, quat_wxyz_to_rotvec, rotvec_geodesic as geodesic,
    rotvec_to_quat_wxyz,
};

/// The actions to execute, by control step.
#[derive(Debug, Clone)]
pub struct ActionBuffer {
    setup: ArmSetup,
    /// `(step, action)`, steps consecutive.
    actions: VecDeque<(usize, Vec<f64>)>,
}

impl ActionBuffer {
    /// An empty buffer for policies of `setup`.
    pub fn new(setup: ArmSetup) -> Self {
        Self {
            setup,
            actions: VecDeque::new(),
        }
    }

    /// Actions buffered.
    pub fn len(&self) -> usize {
        self.actions.len()
    }

    /// Whether nothing is buffered.
    pub fn is_empty(&self) -> bool {
        self.actions.is_empty()
    }

    /// Drops the actions for steps before `now` (they expired while the chunk was on its
    /// way).
    pub fn drop_expired(&mut self, now: usize) {
        while self.actions.front().is_some_and(|(t, _)| *t < now) {
            self.actions.pop_front();
        }
    }

    /// Merges the chunk answering the observation of step `obs_step` at step `now`
    /// (`obs_step <= now`).
    pub fn merge(&mut self, chunk: &[Vec<f64>], obs_step: usize, now: usize) {
        assert!(
            obs_step <= now,
            "a chunk cannot answer a future observation"
        );
        self.drop_expired(now);
        let end = obs_step + chunk.len();
        if end <= now {
            return;
        }
        let fresh = &chunk[now - obs_step..];
        let (buf_start, buf_end) = match (self.actions.front(), self.actions.back()) {
            (Some((a, _)), Some((b, _))) => (*a, b + 1),
            _ => (now, now),
        };
        let (from, to) = (now.max(buf_start), end.min(buf_end));
        let overlap = to.saturating_sub(from);
        for ts in from..to {
            let t = (ts - from + 1) as f64 / (overlap + 1) as f64;
            let old = &mut self.actions[ts - buf_start].1;
            *old = interpolate(self.setup, old, &fresh[ts - now], t);
        }
        for ts in buf_end.max(now)..end {
            self.actions.push_back((ts, fresh[ts - now].clone()));
        }
    }

    /// The action for step `now`, when one is buffered (the buffer's head must be for
    /// `now`).
    pub fn pop(&mut self, now: usize) -> Option<Vec<f64>> {
        let (t, a) = self.actions.pop_front()?;
        assert_eq!(t, now, "the buffer's head is for step {t}, not {now}");
        Some(a)
    }
}

/// `(1 - t) old + t new`, with each arm's rotation vector interpolated on SO(3).
pub fn interpolate(setup: ArmSetup, old: &[f64], new: &[f64], t: f64) -> Vec<f64> {
    let mut out: Vec<f64> = old
        .iter()
        .zip(new)
        .map(|(a, b)| (1.0 - t) * a + t * b)
        .collect();
    let per_arm = ROTVEC_POSE_DIM + HAND_DOF;
    for arm in 0..setup.arms() {
        let r = arm * per_arm + 3;
        let v = geodesic(
            [old[r], old[r + 1], old[r + 2]],
            [new[r], new[r + 1], new[r + 2]],
            t,
        );
        out[r..r + 3].copy_from_slice(&v);
    }
    out
}

/// A policy action (per arm `[xyz, rotvec, hand16]`) as the environment's action (per
/// arm `[xyz, quat wxyz, hand16]`, the DexJoCo raw `action` layout).
pub fn to_env_action(setup: ArmSetup, policy: &[f64]) -> Vec<f64> {
    let per_in = ROTVEC_POSE_DIM + HAND_DOF;
    let mut out = Vec::with_capacity(setup.action_dim());
    for a in policy.chunks_exact(per_in).take(setup.arms()) {
        out.extend_from_slice(&a[..3]);
        out.extend_from_slice(&rotvec_to_quat_wxyz([a[3], a[4], a[5]]));
        out.extend_from_slice(&a[6..]);
    }
    out
}

/// The action that holds the pose of a proprioceptive state (per arm TCP pose, then the
/// hands), as the reference client's `stay()` makes it: each TCP position and rotation
/// vector, and the hands' measured joint positions as their targets.
pub fn stay_action(setup: ArmSetup, proprio: &[f64]) -> Vec<f64> {
    let arms = setup.arms();
    let mut out = Vec::with_capacity(setup.action_rotvec_dim());
    for arm in 0..arms {
        let p = &proprio[arm * 7..arm * 7 + 7];
        out.extend_from_slice(&p[..3]);
        out.extend_from_slice(&quat_wxyz_to_rotvec([p[3], p[4], p[5], p[6]]));
        let h = arms * 7 + arm * HAND_DOF;
        out.extend_from_slice(&proprio[h..h + HAND_DOF]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn act(x: f64, rz: f64) -> Vec<f64> {
        let mut a = vec![0.0; 22];
        a[0] = x;
        a[5] = rz;
        a
    }

    /// The reference's `receive_actions`, step by step: a first chunk fills the buffer;
    /// the next, answering a later observation, drops what expired, blends the overlap
    /// with weights 1/(n+1)..n/(n+1) and appends its tail.
    #[test]
    fn chunks_are_aligned_blended_and_appended_as_the_reference_does() {
        let mut b = ActionBuffer::new(ArmSetup::SingleArm);
        let first: Vec<Vec<f64>> = (0..5).map(|i| act(i as f64, 0.0)).collect();
        // Asked at step 0, merged at step 2 (latency 2): rows 0 and 1 expired.
        b.merge(&first, 0, 2);
        assert_eq!(b.len(), 3);
        assert_eq!(b.pop(2).unwrap()[0], 2.0);
        // Asked at step 3, merged at step 3: overlaps steps 3 and 4, appends 5..7.
        let second: Vec<Vec<f64>> = (0..5).map(|i| act(10.0 + i as f64, 0.0)).collect();
        b.merge(&second, 3, 3);
        assert_eq!(b.len(), 5);
        let xs: Vec<f64> = (3..8).map(|t| b.pop(t).unwrap()[0]).collect();
        // Step 3: (1 - 1/3) * 3 + 1/3 * 10; step 4: (1 - 2/3) * 4 + 2/3 * 11.
        let expect = [
            (2.0 / 3.0) * 3.0 + (1.0 / 3.0) * 10.0,
            (1.0 / 3.0) * 4.0 + (2.0 / 3.0) * 11.0,
            12.0,
            13.0,
            14.0,
        ];
        for (x, e) in xs.iter().zip(expect) {
            assert!((x - e).abs() < 1e-12, "{xs:?}");
        }
        // A chunk wholly in the past is ignored.
        b.merge(&second, 0, 9);
        assert!(b.is_empty());
    }

    #[test]
    fn rotations_are_blended_on_the_sphere_and_convert_to_quaternions() {
        // Half way from +170 deg to -170 deg about z is 180 deg (the short way), not 0.
        let r = geodesic(
            [0.0, 0.0, 170f64.to_radians()],
            [0.0, 0.0, -170f64.to_radians()],
            0.5,
        );
        let angle = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        assert!((angle - std::f64::consts::PI).abs() < 1e-9, "{r:?}");
        let q = to_env_action(ArmSetup::SingleArm, &act(0.5, std::f64::consts::FRAC_PI_2));
        assert_eq!(q.len(), 23);
        assert!((q[3] - (0.5f64).sqrt()).abs() < 1e-12 && (q[6] - (0.5f64).sqrt()).abs() < 1e-12);
        // stay() of the pose it makes gives the rotation vector back.
        let mut proprio = vec![0.0; 23];
        proprio[..7].copy_from_slice(&q[..7]);
        let s = stay_action(ArmSetup::SingleArm, &proprio);
        assert!((s[5] - std::f64::consts::FRAC_PI_2).abs() < 1e-12, "{s:?}");
    }
}
