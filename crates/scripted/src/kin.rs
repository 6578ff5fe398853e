//! Geometry for the planners: vectors, and the privileged poses (bodies, geoms, sites,
//! joints, TCPs) read from the simulation. Quaternion functions are core's `pose` module's,
//! re-exported under the planners' short names.

use dexjoco_core::NameKind;

use crate::PlanError;
use dexjoco_sim::TaskEnv;
use dexjoco_sim::name_id;

/// A 3-vector.
pub(crate) type V3 = [f64; 3];
/// A wxyz quaternion.
pub(crate) type Q = [f64; 4];

pub(crate) use dexjoco_core::pose::{
    axis_angle, nlerp, normalize as qnorm, qmul, to_matrix as qmat, yaw,
};

/// `m * v` for a row-major 3x3 matrix.
pub(crate) fn mulv(m: &[f64; 9], v: V3) -> V3 {
    [
        m[0] * v[0] + m[1] * v[1] + m[2] * v[2],
        m[3] * v[0] + m[4] * v[1] + m[5] * v[2],
        m[6] * v[0] + m[7] * v[1] + m[8] * v[2],
    ]
}

/// `a + b`.
pub(crate) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a - b`.
pub(crate) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `a * k`.
pub(crate) fn scale(a: V3, k: f64) -> V3 {
    [a[0] * k, a[1] * k, a[2] * k]
}

/// The horizontal direction of `v` (its xy part, normalized; z = 0).
pub(crate) fn horizontal(v: V3) -> V3 {
    let n = (v[0] * v[0] + v[1] * v[1]).sqrt();
    [v[0] / n, v[1] / n, 0.0]
}

/// The dot product of `a` and `b`.
pub(crate) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a` scaled to unit length.
pub(crate) fn unit(a: V3) -> V3 {
    scale(a, 1.0 / norm(a))
}

/// The length of `a`.
pub(crate) fn norm(a: V3) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

fn id(env: &TaskEnv, kind: NameKind, name: &str) -> Result<usize, PlanError> {
    name_id(env.data().model(), kind, name).ok_or_else(|| PlanError::lacks(kind.as_str(), name))
}

/// A body's world position and rotation matrix.
pub(crate) fn body(env: &TaskEnv, name: &str) -> Result<(V3, [f64; 9]), PlanError> {
    let b = id(env, NameKind::Body, name)?;
    let d = env.data();
    Ok((d.xpos()[b], d.xmat()[b]))
}

/// A geom's world position and rotation matrix.
pub(crate) fn geom(env: &TaskEnv, name: &str) -> Result<(V3, [f64; 9]), PlanError> {
    let g = id(env, NameKind::Geom, name)?;
    let d = env.data();
    Ok((d.geom_xpos()[g], d.geom_xmat()[g]))
}

/// A site's world position.
pub(crate) fn site(env: &TaskEnv, name: &str) -> Result<V3, PlanError> {
    let s = id(env, NameKind::Site, name)?;
    Ok(env.data().site_xpos()[s])
}

/// A joint's (first) qpos value.
pub(crate) fn joint(env: &TaskEnv, name: &str) -> Result<f64, PlanError> {
    let j = id(env, NameKind::Joint, name)?;
    let a = env.data().model().jnt_qposadr()[j] as usize;
    Ok(env.data().qpos()[a])
}

/// A joint's anchor in the world.
pub(crate) fn anchor(env: &TaskEnv, name: &str) -> Result<V3, PlanError> {
    let j = id(env, NameKind::Joint, name)?;
    Ok(env.data().xanchor()[j])
}

/// Arm `arm`'s TCP position and orientation now.
pub(crate) fn tcp(env: &TaskEnv, arm: usize) -> (V3, Q) {
    env.robot().tcp_pose(env.data(), &env.robot().arms[arm])
}
