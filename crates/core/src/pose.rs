//! Rigid poses in the DexJoCo convention (position in metres, orientation a unit wxyz
//! quaternion): composition, inverse, the pose of one frame in another, interpolation.
//! What object-centric demonstration generation needs to carry an end-effector target
//! from one object pose to another: `new_object * source_object.inverse() * target`.
//! The quaternion functions every crate uses live here (rotation vectors and the geodesic
//! in [`crate::rotation`], SciPy's formulas); the planners' geometry and generate's
//! transforms call them, nothing defines its own.

use serde::{Deserialize, Serialize};

/// A 3-vector.
pub type Vec3 = [f64; 3];
/// A wxyz quaternion.
pub type Quat = [f64; 4];

/// A rigid transform: rotate by `quat`, then translate by `pos`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Position (m).
    pub pos: Vec3,
    /// Orientation, wxyz, unit norm.
    pub quat: Quat,
}

impl Default for Pose {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Pose {
    /// The identity.
    pub const IDENTITY: Self = Self {
        pos: [0.0; 3],
        quat: [1.0, 0.0, 0.0, 0.0],
    };

    /// A pose from a position and a quaternion (normalized here).
    pub fn new(pos: Vec3, quat: Quat) -> Self {
        Self {
            pos,
            quat: normalize(quat),
        }
    }

    /// The pose of 7 values `[x, y, z, qw, qx, qy, qz]` (an action's or a state's pose).
    pub fn from_slice(v: &[f64]) -> Self {
        Self::new([v[0], v[1], v[2]], [v[3], v[4], v[5], v[6]])
    }

    /// Writes `[x, y, z, qw, qx, qy, qz]` into the first 7 values of `out`.
    pub fn write(&self, out: &mut [f64]) {
        out[..3].copy_from_slice(&self.pos);
        out[3..7].copy_from_slice(&self.quat);
    }

    /// `self * other`: `other` expressed in `self`'s frame, as a pose in the frame
    /// `self` is expressed in.
    pub fn compose(&self, other: &Self) -> Self {
        Self {
            pos: add(self.pos, rotate(self.quat, other.pos)),
            quat: normalize(qmul(self.quat, other.quat)),
        }
    }

    /// The inverse transform.
    pub fn inverse(&self) -> Self {
        let q = conjugate(self.quat);
        let p = rotate(q, self.pos);
        Self {
            pos: [-p[0], -p[1], -p[2]],
            quat: q,
        }
    }

    /// `other` expressed in this pose's frame: `self.inverse() * other`.
    pub fn relative(&self, other: &Self) -> Self {
        self.inverse().compose(other)
    }

    /// A point of this frame in the outer frame.
    pub fn apply(&self, point: Vec3) -> Vec3 {
        add(self.pos, rotate(self.quat, point))
    }

    /// The pose `t` of the way from `self` to `to` (t in [0, 1]): positions linearly,
    /// orientations by spherical interpolation along the shorter arc.
    pub fn interpolate(&self, to: &Self, t: f64) -> Self {
        Self {
            pos: [
                self.pos[0] + (to.pos[0] - self.pos[0]) * t,
                self.pos[1] + (to.pos[1] - self.pos[1]) * t,
                self.pos[2] + (to.pos[2] - self.pos[2]) * t,
            ],
            quat: slerp(self.quat, to.quat, t),
        }
    }

    /// Distance between the positions (m).
    pub fn distance(&self, other: &Self) -> f64 {
        let d = sub(self.pos, other.pos);
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
    }

    /// The rotation angle from this orientation to `other`'s (rad, in [0, pi]).
    pub fn angle_to(&self, other: &Self) -> f64 {
        let d: f64 = (0..4).map(|i| self.quat[i] * other.quat[i]).sum();
        2.0 * d.abs().min(1.0).acos()
    }
}

/// Hamilton product `a * b`.
pub fn qmul(a: Quat, b: Quat) -> Quat {
    [
        a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3],
        a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2],
        a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1],
        a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0],
    ]
}

/// The conjugate (the inverse rotation of a unit quaternion).
pub fn conjugate(q: Quat) -> Quat {
    [q[0], -q[1], -q[2], -q[3]]
}

/// `q` at unit norm (the identity for the zero quaternion).
pub fn normalize(q: Quat) -> Quat {
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if n < crate::ZERO_QUAT_EPS {
        return [1.0, 0.0, 0.0, 0.0];
    }
    [q[0] / n, q[1] / n, q[2] / n, q[3] / n]
}

/// `v` rotated by the unit quaternion `q`.
pub fn rotate(q: Quat, v: Vec3) -> Vec3 {
    // v + 2 w (u x v) + 2 u x (u x v), u the vector part.
    let u = [q[1], q[2], q[3]];
    let t = scale(cross(u, v), 2.0);
    add(add(v, scale(t, q[0])), cross(u, t))
}

/// The rotation by `angle` (rad) about the unit `axis`.
pub fn axis_angle(axis: Vec3, angle: f64) -> Quat {
    let (s, c) = (angle / 2.0).sin_cos();
    [c, axis[0] * s, axis[1] * s, axis[2] * s]
}

/// The rotation by `angle` (rad) about world z.
pub fn yaw(angle: f64) -> Quat {
    axis_angle([0.0, 0.0, 1.0], angle)
}

/// Normalized linear interpolation from `a` to `b` (the shorter way round).
pub fn nlerp(a: Quat, b: Quat, t: f64) -> Quat {
    let dot: f64 = (0..4).map(|i| a[i] * b[i]).sum();
    let s = if dot < 0.0 { -1.0 } else { 1.0 };
    normalize([
        a[0] + (s * b[0] - a[0]) * t,
        a[1] + (s * b[1] - a[1]) * t,
        a[2] + (s * b[2] - a[2]) * t,
        a[3] + (s * b[3] - a[3]) * t,
    ])
}

/// The row-major rotation matrix of `q` (normalized first).
pub fn to_matrix(q: Quat) -> [f64; 9] {
    let [w, x, y, z] = normalize(q);
    [
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y - w * z),
        2.0 * (x * z + w * y),
        2.0 * (x * y + w * z),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z - w * x),
        2.0 * (x * z - w * y),
        2.0 * (y * z + w * x),
        1.0 - 2.0 * (x * x + y * y),
    ]
}

/// Spherical linear interpolation from `a` to `b` along the shorter arc.
pub fn slerp(a: Quat, b: Quat, t: f64) -> Quat {
    let mut d: f64 = (0..4).map(|i| a[i] * b[i]).sum();
    let b = if d < 0.0 {
        d = -d;
        [-b[0], -b[1], -b[2], -b[3]]
    } else {
        b
    };
    if d > 1.0 - 1e-12 {
        // Nearly the same orientation: linear, then normalized.
        return normalize(std::array::from_fn(|i| a[i] + (b[i] - a[i]) * t));
    }
    let theta = d.acos();
    let s = theta.sin();
    let (wa, wb) = (((1.0 - t) * theta).sin() / s, (t * theta).sin() / s);
    normalize(std::array::from_fn(|i| wa * a[i] + wb * b[i]))
}

fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn scale(a: Vec3, k: f64) -> Vec3 {
    [a[0] * k, a[1] * k, a[2] * k]
}

fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Pose, b: &Pose, tol: f64) -> bool {
        a.distance(b) < tol && a.angle_to(b) < tol
    }

    fn some_pose(k: f64) -> Pose {
        Pose::new(
            [0.3 * k, -0.2 + k, 0.9 - 0.1 * k],
            [0.3 + k, -0.5, 0.2 * k, 0.7],
        )
    }

    #[test]
    fn compose_inverse_and_relative_agree() {
        let (a, b) = (some_pose(0.4), some_pose(-1.3));
        assert!(close(&a.compose(&a.inverse()), &Pose::IDENTITY, 1e-12));
        assert!(close(&a.compose(&a.relative(&b)), &b, 1e-12));
        // A point through a frame and back.
        let p = [0.1, -0.7, 2.0];
        let back = a.inverse().apply(a.apply(p));
        assert!((0..3).all(|i| (back[i] - p[i]).abs() < 1e-12));
        // Rotation about z by 90 degrees takes x to y.
        let z90 = Pose::new([0.0; 3], [0.5f64.sqrt(), 0.0, 0.0, 0.5f64.sqrt()]);
        let y = z90.apply([1.0, 0.0, 0.0]);
        assert!((y[0]).abs() < 1e-15 && (y[1] - 1.0).abs() < 1e-15);
    }

    #[test]
    fn a_target_carried_to_its_own_object_pose_is_unchanged() {
        // new_object * source_object^-1 * target with new == source: the target itself.
        let (object, target) = (some_pose(0.8), some_pose(2.1));
        let carried = object.compose(&object.relative(&target));
        assert!(close(&carried, &target, 1e-12));
    }

    #[test]
    fn interpolation_ends_at_both_poses_and_takes_the_short_arc() {
        let (a, b) = (some_pose(0.1), some_pose(0.9));
        assert!(close(&a.interpolate(&b, 0.0), &a, 1e-12));
        assert!(close(&a.interpolate(&b, 1.0), &b, 1e-12));
        let mid = a.interpolate(&b, 0.5);
        let (da, db) = (a.angle_to(&mid), mid.angle_to(&b));
        assert!((da - db).abs() < 1e-9, "{da} {db}");
        // -q is the same rotation: no long way round.
        let neg = Pose::new(b.pos, b.quat.map(|v| -v));
        assert!(a.interpolate(&neg, 0.5).angle_to(&mid) < 1e-9);
    }
}
