//! What the fold_glasses planner reads from the model: the glasses' parts (front,
//! temples, hinges) and the table's near edge, as bounding boxes of collision geoms.

use super::DAMPED;
use crate::PlanError;
use crate::kin::{self, V3};
use dexjoco_sim::TaskEnv;

/// The joint id of `joint` and the id of the body it moves.
pub(super) fn joint_body(e: &TaskEnv, joint: &str) -> Result<(usize, usize), PlanError> {
    let m = e.data().model();
    let j = dexjoco_sim::name_id(m, dexjoco_core::NameKind::Joint, joint)
        .ok_or_else(|| PlanError::lacks("joint", joint))?;
    Ok((j, m.jnt_bodyid()[j] as usize))
}

/// Whether hinge `joint` is damped (see [`DAMPED`]).
pub(super) fn hinge_damped(e: &TaskEnv, joint: &str) -> Result<bool, PlanError> {
    let (j, _) = joint_body(e, joint)?;
    let m = e.data().model();
    Ok(m.dof_damping()[m.jnt_dofadr()[j] as usize] >= DAMPED)
}

/// The x of the table's near edge (the robot's side): the bounding box of the body
/// holding site `table_top`.
pub(super) fn table_near_edge(e: &TaskEnv) -> Result<f64, PlanError> {
    let m = e.data().model();
    let s = dexjoco_sim::name_id(m, dexjoco_core::NameKind::Site, "table_top")
        .ok_or_else(|| PlanError::lacks("site", "table_top"))?;
    let b = m.site_bodyid()[s] as usize;
    let (c, h) = body_box(e, b);
    let d = e.data();
    let xm = d.xmat()[b];
    let x = d.xpos()[b][0] + kin::mulv(&xm, c)[0];
    Ok(x - (0..3).map(|i| xm[i].abs() * h[i]).sum::<f64>())
}

/// The union of the collision geoms' bounding boxes of body `b`, in the body's frame:
/// its centre and half sizes.
pub(super) fn body_box(e: &TaskEnv, b: usize) -> (V3, V3) {
    let m = e.data().model();
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for g in 0..m.ffi().ngeom as usize {
        if m.geom_bodyid()[g] as usize != b
            || (m.geom_contype()[g] == 0 && m.geom_conaffinity()[g] == 0)
        {
            continue;
        }
        let bb = m.geom_aabb()[g];
        let r = kin::qmat(m.geom_quat()[g]);
        for k in 0..8 {
            let c: V3 = std::array::from_fn(|i| {
                let s = if k >> i & 1 == 1 { 1.0 } else { -1.0 };
                bb[i] + s * bb[3 + i]
            });
            let p = kin::add(m.geom_pos()[g], kin::mulv(&r, c));
            for i in 0..3 {
                lo[i] = lo[i].min(p[i]);
                hi[i] = hi[i].max(p[i]);
            }
        }
    }
    let c = std::array::from_fn(|i| (lo[i] + hi[i]) / 2.0);
    let h = std::array::from_fn(|i| (hi[i] - lo[i]) / 2.0);
    (c, h)
}

/// The centre (world) of the bounding box of the temple on hinge `joint` (the body the
/// joint moves).
pub(super) fn temple(e: &TaskEnv, joint: &str) -> Result<V3, PlanError> {
    let (_, b) = joint_body(e, joint)?;
    Ok(box_centre(e, b))
}

/// The front of the glasses (the collision geoms of body `glass`): its bounding box's
/// centre (world), a row-major matrix whose columns are the box's thin, wide and tall
/// axes (world; the tall one pointing up when the glasses stand), and its half sizes
/// along them.
pub(super) fn front(e: &TaskEnv) -> Result<(V3, [f64; 9], V3), PlanError> {
    let m = e.data().model();
    let b = dexjoco_sim::name_id(m, dexjoco_core::NameKind::Body, "glass")
        .ok_or_else(|| PlanError::lacks("body", "glass"))?;
    let (_, h) = body_box(e, b);
    let d = e.data();
    let xm = d.xmat()[b];
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| h[a].total_cmp(&h[b]));
    let [thin, tall, wide] = order;
    let col = |i: usize| [xm[i], xm[3 + i], xm[6 + i]];
    let up = col(tall);
    let s = if up[2] < 0.0 { -1.0 } else { 1.0 };
    let (a, w, u) = (col(thin), col(wide), kin::scale(up, s));
    let fm = [a[0], w[0], u[0], a[1], w[1], u[1], a[2], w[2], u[2]];
    Ok((box_centre(e, b), fm, [h[thin], h[wide], h[tall]]))
}

/// The centre (world) of body `b`'s collision bounding box ([`body_box`]).
pub(super) fn box_centre(e: &TaskEnv, b: usize) -> V3 {
    let (c, _) = body_box(e, b);
    let d = e.data();
    kin::add(d.xpos()[b], kin::mulv(&d.xmat()[b], c))
}
