//! Rotations in the DexJoCo convention: quaternions are wxyz; a quaternion becomes a
//! rotation vector after normalization, and the zero quaternion becomes the zero vector.
//! The formulas follow SciPy's `Rotation.from_quat(.., scalar_first=True).as_rotvec()` and
//! `Rotation.from_rotvec(..).as_quat(scalar_first=True)` (including their Taylor
//! expansions near zero angle), so values agree with SciPy to rounding.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use crate::layout::{HAND_DOF, POSE_DIM, ROTVEC_POSE_DIM};

/// Quaternions with a norm below this are treated as zero (-> zero rotation vector).
pub const ZERO_QUAT_EPS: f64 = 1e-12;

/// Rotation vector (axis * angle, angle in [0, pi]) of a wxyz quaternion, normalized
/// first; the zero quaternion gives the zero vector.
pub fn quat_wxyz_to_rotvec(q: [f64; 4]) -> [f64; 3] {
    let q = Quaternion::new(q[0], q[1], q[2], q[3]);
    let norm = q.norm();
    if norm < ZERO_QUAT_EPS {
        return [0.0; 3];
    }
    let mut q = q / norm;
    // The canonical sign of the same rotation: w > 0, or, when w is 0, the first nonzero
    // of x, y, z positive. It gives the angle in [0, pi] and, at exactly pi, the same axis
    // direction SciPy picks.
    let flip = if q.w != 0.0 {
        q.w < 0.0
    } else if q.i != 0.0 {
        q.i < 0.0
    } else if q.j != 0.0 {
        q.j < 0.0
    } else {
        q.k < 0.0
    };
    if flip {
        q = -q;
    }
    let v: Vector3<f64> = q.imag();
    let angle = 2.0 * v.norm().atan2(q.w);
    let scale = if angle <= 1e-3 {
        let a2 = angle * angle;
        2.0 + a2 / 12.0 + 7.0 * a2 * a2 / 2880.0
    } else {
        angle / (angle / 2.0).sin()
    };
    let r = v * scale;
    [r.x, r.y, r.z]
}

/// Unit wxyz quaternion (w >= 0 for angles up to pi) of a rotation vector.
pub fn rotvec_to_quat_wxyz(r: [f64; 3]) -> [f64; 4] {
    let v = Vector3::new(r[0], r[1], r[2]);
    let angle = v.norm();
    let scale = if angle <= 1e-3 {
        let a2 = angle * angle;
        0.5 - a2 / 48.0 + a2 * a2 / 3840.0
    } else {
        (angle / 2.0).sin() / angle
    };
    let xyz = v * scale;
    [(angle / 2.0).cos(), xyz.x, xyz.y, xyz.z]
}

/// Converts one action row (per arm [xyz, quat wxyz, hand16]) into its rotation-vector
/// form (per arm [xyz, rotvec, hand16]). `out` must be 22/23 of `action`'s length.
pub fn action_to_rotvec(action: &[f64], out: &mut [f64]) {
    let per_in = POSE_DIM + HAND_DOF;
    let per_out = ROTVEC_POSE_DIM + HAND_DOF;
    for (a, o) in action
        .chunks_exact(per_in)
        .zip(out.chunks_exact_mut(per_out))
    {
        o[..3].copy_from_slice(&a[..3]);
        o[3..6].copy_from_slice(&quat_wxyz_to_rotvec([a[3], a[4], a[5], a[6]]));
        o[6..].copy_from_slice(&a[7..]);
    }
}

fn unit_quaternion(r: [f64; 3]) -> UnitQuaternion<f64> {
    let [w, x, y, z] = rotvec_to_quat_wxyz(r);
    UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z))
}

fn unit_rotvec(q: UnitQuaternion<f64>) -> [f64; 3] {
    quat_wxyz_to_rotvec([q.w, q.i, q.j, q.k])
}

/// The rotation `t` of the way from `r0` to `r1` along the shorter geodesic, as SciPy
/// computes it in the reference: `r0 * exp(t * log(r0^-1 * r1))`.
pub fn rotvec_geodesic(r0: [f64; 3], r1: [f64; 3], t: f64) -> [f64; 3] {
    if t <= 0.0 {
        return r0;
    }
    if t >= 1.0 {
        return r1;
    }
    let (q0, q1) = (unit_quaternion(r0), unit_quaternion(r1));
    let rel = unit_rotvec(q0.inverse() * q1);
    unit_rotvec(q0 * unit_quaternion(rel.map(|v| v * t)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn identity_zero_and_half_turn() {
        assert_eq!(quat_wxyz_to_rotvec([1.0, 0.0, 0.0, 0.0]), [0.0; 3]);
        assert_eq!(quat_wxyz_to_rotvec([0.0; 4]), [0.0; 3]);
        let r = quat_wxyz_to_rotvec([0.0, 0.0, 0.0, 1.0]);
        assert!((r[2] - std::f64::consts::PI).abs() < 1e-15);
        // negative w is the same rotation
        let a = quat_wxyz_to_rotvec([0.8, 0.6, 0.0, 0.0]);
        let b = quat_wxyz_to_rotvec([-0.8, -0.6, 0.0, 0.0]);
        assert_eq!(a, b);
    }

    #[test]
    fn round_trip() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for _ in 0..1000 {
            let q: [f64; 4] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            let r = quat_wxyz_to_rotvec(q);
            let back = rotvec_to_quat_wxyz(r);
            let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
            let s = if q[0] < 0.0 { -1.0 } else { 1.0 };
            for k in 0..4 {
                assert!(
                    (back[k] - s * q[k] / n).abs() < 1e-12,
                    "{q:?} -> {r:?} -> {back:?}"
                );
            }
        }
    }
}
