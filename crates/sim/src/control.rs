//! DexJoCo control: the operational-space arm controller and the Allegro hand position
//! targets, per arm, as in the reference (dexjoco-sim.md, dexjoco-task-semantics.md B).

use dexjoco_core::{ArmSetup, HAND_DOF, NameKind, POSE_DIM};
use mujoco_rs::mujoco_c::{mju_mat2Quat, mju_mulQuat, mju_negQuat, mju_quat2Vel};
use mujoco_rs::prelude::{MjData, MjModel};
use mujoco_rs::wrappers::mj_model::traits::ModelType;
use nalgebra::{SMatrix, SVector};

use crate::checker::Resolver;
use crate::error::SimError;

/// Arm joints per arm.
pub const ARM_DOF: usize = 7;
/// Physics substeps per control step.
pub const SUBSTEPS: usize = 10;
/// A pose target is "hold" when every entry is within this of zero.
pub const HOLD_EPS: f64 = 1e-8;
/// The Panda home joint pose.
pub const ARM_HOME: [f64; ARM_DOF] = [
    0.0,
    -0.785,
    0.0,
    -2.35,
    0.0,
    1.57,
    std::f64::consts::FRAC_PI_4,
];
/// Home thumb base joint (written as float32 except in the microwave task).
pub const THUMB_HOME: f64 = 0.263;

/// Gains of the operational-space controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OscGains {
    /// Position stiffness (x, y, z).
    pub kp_pos: f64,
    /// Orientation stiffness.
    pub kp_ori: f64,
    /// Damping ratio (kd = ratio * 2 * sqrt(kp)).
    pub damping_ratio: f64,
    /// Null-space stiffness toward the home pose.
    pub kp_null: f64,
}

impl Default for OscGains {
    fn default() -> Self {
        Self {
            kp_pos: 400.0,
            kp_ori: 200.0,
            damping_ratio: 4.0,
            kp_null: 0.5,
        }
    }
}

/// The finger order of the right (and single) hand in actions and state.
const RIGHT_FINGERS: [&str; 4] = ["ff", "mf", "rf", "th"];
/// The left hand's order (reversed finger lists).
const LEFT_FINGERS: [&str; 4] = ["rf", "mf", "ff", "th"];

/// One Panda + Allegro, resolved to model indices.
#[derive(Debug, Clone)]
pub struct Arm {
    /// `arm`, `right` or `left`.
    pub name: &'static str,
    /// qpos addresses of joint1..7.
    pub qpos: [usize; ARM_DOF],
    /// dof addresses of joint1..7.
    pub dofs: [usize; ARM_DOF],
    /// Motor actuators 1..7.
    pub motors: [usize; ARM_DOF],
    /// Hand position actuators, in this arm's action order.
    pub hand_actuators: [usize; HAND_DOF],
    /// Hand joint qpos addresses, in this arm's state order.
    pub hand_qpos: [usize; HAND_DOF],
    /// Hand jointpos sensor addresses, in this arm's state order.
    pub hand_sensors: [usize; HAND_DOF],
    /// qpos address of the thumb base joint.
    pub thumb_base_qpos: usize,
    /// The TCP site (`attachment_site`).
    pub site: usize,
    /// Index of the target mocap body.
    pub mocap: usize,
    /// framepos / framequat sensor addresses of the TCP.
    pub tcp_pos_sensor: usize,
    /// See `tcp_pos_sensor`.
    pub tcp_quat_sensor: usize,
}

/// The robot of a task: one arm or two (right first).
#[derive(Debug, Clone)]
pub struct Robot {
    /// The setup.
    pub setup: ArmSetup,
    /// The arms in action order.
    pub arms: Vec<Arm>,
    /// Controller gains.
    pub gains: OscGains,
}

impl Robot {
    /// Resolves the robot of a setup in a model (names as in the reference scenes);
    /// every missing name is listed in the error.
    pub fn new(model: &MjModel, setup: ArmSetup) -> Result<Self, SimError> {
        let mut r = Resolver::new(model);
        let qadr = model.jnt_qposadr();
        let dadr = model.jnt_dofadr();
        let sadr = model.sensor_adr();
        let sides: &[(&'static str, &str, &str)] = match setup {
            ArmSetup::SingleArm => &[("arm", "", "target")],
            ArmSetup::Bimanual => &[
                ("right", "_right", "target_right"),
                ("left", "_left", "target_left"),
            ],
        };
        let mut arms = Vec::new();
        for &(name, sfx, target) in sides {
            let joint = |r: &mut Resolver, n: &str| {
                let id = r.id(NameKind::Joint, n);
                (
                    qadr.get(id).map_or(0, |a| *a as usize),
                    dadr.get(id).map_or(0, |a| *a as usize),
                )
            };
            let mut qpos = [0; ARM_DOF];
            let mut dofs = [0; ARM_DOF];
            let mut motors = [0; ARM_DOF];
            for i in 0..ARM_DOF {
                (qpos[i], dofs[i]) = joint(&mut r, &format!("joint{}{sfx}", i + 1));
                motors[i] = r.id(NameKind::Actuator, &format!("actuator{}{sfx}", i + 1));
            }
            let fingers = if name == "left" {
                LEFT_FINGERS
            } else {
                RIGHT_FINGERS
            };
            let hand_prefix = if name == "left" {
                "allegro_left"
            } else {
                "allegro_right"
            };
            let mut hand_actuators = [0; HAND_DOF];
            let mut hand_qpos = [0; HAND_DOF];
            let mut hand_sensors = [0; HAND_DOF];
            for (f, finger) in fingers.iter().enumerate() {
                for k in 0..4 {
                    let i = 4 * f + k;
                    let act = if *finger == "th" {
                        format!("tha{k}{sfx}")
                    } else {
                        format!("{finger}a{k}{sfx}")
                    };
                    hand_actuators[i] = r.id(NameKind::Actuator, &act);
                    hand_qpos[i] = joint(&mut r, &format!("{finger}j{k}{sfx}")).0;
                    let s = r.id(NameKind::Sensor, &format!("{hand_prefix}/{finger}j{k}_pos"));
                    hand_sensors[i] = sadr.get(s).map_or(0, |a| *a as usize);
                }
            }
            let thumb_base_qpos = joint(&mut r, &format!("thj0{sfx}")).0;
            let site = r.id(NameKind::Site, &format!("attachment_site{sfx}"));
            let body = r.id(NameKind::Body, target);
            let mocap = model.body_mocapid().get(body).copied().unwrap_or(-1);
            let ps = r.id(NameKind::Sensor, &format!("franka/flange_pos{sfx}"));
            let qs = r.id(NameKind::Sensor, &format!("franka/flange_quat{sfx}"));
            if body != usize::MAX && mocap < 0 {
                return Err(SimError::NotMocap(target.to_string()));
            }
            arms.push(Arm {
                name,
                qpos,
                dofs,
                motors,
                hand_actuators,
                hand_qpos,
                hand_sensors,
                thumb_base_qpos,
                site,
                mocap: mocap.max(0) as usize,
                tcp_pos_sensor: sadr.get(ps).map_or(0, |a| *a as usize),
                tcp_quat_sensor: sadr.get(qs).map_or(0, |a| *a as usize),
            });
        }
        r.finish(&format!("the {setup:?} robot"))?;
        Ok(Self {
            setup,
            arms,
            gains: OscGains::default(),
        })
    }

    /// Writes an action's pose targets into the mocap bodies (per arm; an all-zero pose
    /// holds the last target) and returns the hand targets per arm. The quaternion is
    /// copied as given, not normalized.
    pub fn apply_pose_targets<M: ModelType>(
        &self,
        data: &mut MjData<M>,
        action: &[f64],
    ) -> Vec<[f64; HAND_DOF]> {
        let per = POSE_DIM + HAND_DOF;
        let mut hands = Vec::new();
        for (k, arm) in self.arms.iter().enumerate() {
            let a = &action[k * per..(k + 1) * per];
            let pose = &a[..POSE_DIM];
            if !pose.iter().all(|v| v.abs() <= HOLD_EPS) {
                data.mocap_pos_mut()[arm.mocap].copy_from_slice(&pose[..3]);
                data.mocap_quat_mut()[arm.mocap].copy_from_slice(&pose[3..7]);
            }
            let mut h = [0.0; HAND_DOF];
            h.copy_from_slice(&a[POSE_DIM..]);
            hands.push(h);
        }
        hands
    }

    /// One substep's controls: arm torques from the operational-space controller (on the
    /// kinematics the data holds: those of the previous `mj_step`) and hand targets.
    pub fn write_controls<M: ModelType>(&self, data: &mut MjData<M>, hands: &[[f64; HAND_DOF]]) {
        for (arm, hand) in self.arms.iter().zip(hands) {
            let tau = self.osc(data, arm);
            let ctrl = data.ctrl_mut();
            for i in 0..ARM_DOF {
                ctrl[arm.motors[i]] = tau[i];
            }
            for i in 0..HAND_DOF {
                ctrl[arm.hand_actuators[i]] = hand[i];
            }
        }
    }

    /// One control step: pose targets, then [`SUBSTEPS`] x (controls, `mj_step`), calling
    /// `after_substep` after each `mj_step`.
    pub fn step<M: ModelType>(
        &self,
        data: &mut MjData<M>,
        action: &[f64],
        mut after_substep: impl FnMut(&MjData<M>),
    ) {
        let hands = self.apply_pose_targets(data, action);
        for _ in 0..SUBSTEPS {
            self.write_controls(data, &hands);
            data.step();
            after_substep(data);
        }
    }

    /// Arm torques of the operational-space controller for one arm.
    pub fn osc<M: ModelType>(&self, data: &MjData<M>, arm: &Arm) -> [f64; ARM_DOF] {
        let g = &self.gains;
        let nv = data.model().ffi().nv as usize;
        let (jacp, jacr) = data.jac_site(true, true, arm.site);
        let mut j = SMatrix::<f64, 6, ARM_DOF>::zeros();
        for c in 0..ARM_DOF {
            for r in 0..3 {
                j[(r, c)] = jacp[r * nv + arm.dofs[c]];
                j[(r + 3, c)] = jacr[r * nv + arm.dofs[c]];
            }
        }
        let mut full = vec![0.0; nv * nv];
        data.full_m(&mut full).expect("nv * nv buffer");
        let m =
            SMatrix::<f64, ARM_DOF, ARM_DOF>::from_fn(|r, c| full[arm.dofs[r] * nv + arm.dofs[c]]);
        let qpos = data.qpos();
        let qvel = data.qvel();
        let q = SVector::<f64, ARM_DOF>::from_fn(|i, _| qpos[arm.qpos[i]]);
        let dq = SVector::<f64, ARM_DOF>::from_fn(|i, _| qvel[arm.dofs[i]]);

        // Position error and velocity.
        let x = data.site_xpos()[arm.site];
        let x_des = data.mocap_pos()[arm.mocap];
        let quat_des = data.mocap_quat()[arm.mocap];
        let twist = j * dq;
        let kd_p = g.damping_ratio * 2.0 * g.kp_pos.sqrt();
        let kd_o = g.damping_ratio * 2.0 * g.kp_ori.sqrt();
        let e_o = orientation_error(&data.site_xmat()[arm.site], &quat_des);
        let mut ddx = SVector::<f64, 6>::zeros();
        for i in 0..3 {
            ddx[i] = -g.kp_pos * (x[i] - x_des[i]) - kd_p * twist[i];
            ddx[i + 3] = -g.kp_ori * e_o[i] - kd_o * twist[i + 3];
        }

        let m_inv = m
            .try_inverse()
            .unwrap_or_else(|| m.pseudo_inverse(1e-12).expect("svd"));
        let mx_inv = j * m_inv * j.transpose();
        let mx = if mx_inv.determinant().abs() >= 1e-2 {
            mx_inv.try_inverse().unwrap_or_else(|| pinv(&mx_inv))
        } else {
            pinv(&mx_inv)
        };
        let mut tau = j.transpose() * mx * ddx;

        let kd_null = g.damping_ratio * 2.0 * g.kp_null.sqrt();
        let home = SVector::<f64, ARM_DOF>::from(ARM_HOME);
        let ddq = g.kp_null * (home - q) - kd_null * dq;
        let jbar = m_inv * j.transpose() * mx;
        let null = SMatrix::<f64, ARM_DOF, ARM_DOF>::identity() - j.transpose() * jbar.transpose();
        tau += null * ddq;
        let bias = data.qfrc_bias();
        let mut out = [0.0; ARM_DOF];
        for i in 0..ARM_DOF {
            out[i] = tau[i] + bias[arm.dofs[i]];
        }
        out
    }

    /// The current TCP pose of an arm from its site (position, quaternion wxyz).
    pub fn tcp_pose<M: ModelType>(&self, data: &MjData<M>, arm: &Arm) -> ([f64; 3], [f64; 4]) {
        (
            data.site_xpos()[arm.site],
            mat_to_quat(&data.site_xmat()[arm.site]),
        )
    }
}

/// Pseudo-inverse with numpy's relative cutoff rcond = 1e-2.
fn pinv(a: &SMatrix<f64, 6, 6>) -> SMatrix<f64, 6, 6> {
    let svd = a.svd(true, true);
    let cutoff = 1e-2 * svd.singular_values.max();
    svd.pseudo_inverse(cutoff)
        .unwrap_or_else(|_| SMatrix::zeros())
}

/// wxyz quaternion of a row-major rotation matrix (MuJoCo's `mju_mat2Quat`).
pub fn mat_to_quat(mat: &[f64; 9]) -> [f64; 4] {
    let mut q = [0.0; 4];
    // SAFETY: both pointers reference fixed-size local arrays of the sizes MuJoCo expects.
    unsafe { mju_mat2Quat(&mut q, mat) };
    q
}

/// Orientation error as a rotation vector: the rotation from the desired to the current
/// orientation, `quat2vel(q * conj(q_des))`, with q sign-aligned to q_des first.
pub fn orientation_error(xmat: &[f64; 9], quat_des: &[f64; 4]) -> [f64; 3] {
    let mut q = mat_to_quat(xmat);
    let dot: f64 = (0..4).map(|i| q[i] * quat_des[i]).sum();
    if dot < 0.0 {
        q.iter_mut().for_each(|v| *v = -*v);
    }
    let mut conj = [0.0; 4];
    let mut err = [0.0; 4];
    let mut vel = [0.0; 3];
    // SAFETY: every pointer references a fixed-size local array of the size MuJoCo
    // expects for a quaternion (4) or a 3-vector; the inputs are not aliased outputs.
    unsafe {
        mju_negQuat(&mut conj, quat_des);
        mju_mulQuat(&mut err, &q, &conj);
        mju_quat2Vel(&mut vel, &err, 1.0);
    }
    vel
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientation_error_is_the_rotation_vector_to_the_target() {
        let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        assert_eq!(
            orientation_error(&identity, &[1.0, 0.0, 0.0, 0.0]),
            [0.0; 3]
        );
        // Target rotated +0.2 rad about z: the current pose is -0.2 about z from it.
        let h = 0.1f64;
        let e = orientation_error(&identity, &[h.cos(), 0.0, 0.0, h.sin()]);
        assert!((e[2] + 0.2).abs() < 1e-12 && e[0].abs() < 1e-15, "{e:?}");
        // The sign of the target quaternion does not matter.
        let e2 = orientation_error(&identity, &[-h.cos(), 0.0, 0.0, -h.sin()]);
        assert!((e2[2] + 0.2).abs() < 1e-12, "{e2:?}");
    }
}
