//! Evaluating a compiled condition graph on the simulation: one node at a time, in
//! evaluation order, reading positions, frames, joints and contacts from `MjData`.

use std::collections::BTreeSet;

use dexjoco_core::BoxAxes;
use mujoco_rs::prelude::MjData;
use mujoco_rs::wrappers::mj_model::traits::ModelType;

use super::SuccessChecker;
use super::compile::{Compiled, Frame, Geoms, Joint, Point};
use crate::primitives::{self as p, DiskState};

impl SuccessChecker {
    pub(super) fn eval<M: ModelType>(
        &mut self,
        i: usize,
        data: &mut MjData<M>,
    ) -> (bool, Vec<f64>) {
        // Inputs come earlier in the order, so their values of this step are ready.
        let inputs: Vec<bool> = match &self.nodes[i] {
            Compiled::All(v) | Compiled::Any(v) => v.iter().map(|p| self.read(*p)).collect(),
            Compiled::Seq { events, .. } => events.iter().map(|p| self.read(*p)).collect(),
            Compiled::Not(p)
            | Compiled::Held { of: p, .. }
            | Compiled::Rising { of: p, .. }
            | Compiled::Falling { of: p, .. }
            | Compiled::Counter { of: p, .. } => vec![self.read(*p)],
            Compiled::Latch { set, clear, .. } => {
                vec![self.read(*set), clear.is_some_and(|c| self.read(c))]
            }
            _ => Vec::new(),
        };
        let number = match &self.nodes[i] {
            Compiled::ValueCmp { of, .. } => self.num(*of),
            _ => 0.0,
        };
        match &mut self.nodes[i] {
            Compiled::Nail { .. } | Compiled::Keypad { .. } | Compiled::Hanoi { .. } => {
                eval_mechanic(&mut self.nodes[i], data)
            }
            Compiled::Grasp {
                fingers,
                palm,
                object,
                min_fingers,
                opposed,
            } => eval_grasp(fingers, palm, object, (*min_fingers, *opposed), data),
            Compiled::All(_)
            | Compiled::Any(_)
            | Compiled::Not(_)
            | Compiled::Held { .. }
            | Compiled::Rising { .. }
            | Compiled::Falling { .. }
            | Compiled::Counter { .. }
            | Compiled::Latch { .. }
            | Compiled::Seq { .. }
            | Compiled::ValueCmp { .. } => eval_logic(&mut self.nodes[i], &inputs, number),
            node => (eval_sensing(node, data), vec![]),
        }
    }
}

/// A grasp: which fingers (thumb last) and whether the palm touch the object; true when
/// at least `min_fingers` of the other fingers do and the thumb or the palm opposes them
/// (`opposed`), else when any `min_fingers` fingers do. Output: the fingers touching.
fn eval_grasp<M: ModelType>(
    fingers: &[BTreeSet<usize>],
    palm: &BTreeSet<usize>,
    object: &Geoms,
    (min_fingers, opposed): (u32, bool),
    data: &MjData<M>,
) -> (bool, Vec<f64>) {
    let mut touching = vec![false; fingers.len()];
    let mut palm_touches = false;
    for c in data.contact() {
        let (g1, g2) = (c.geom[0] as usize, c.geom[1] as usize);
        let hand_geom = if object.contains(g2) {
            g1
        } else if object.contains(g1) {
            g2
        } else {
            continue;
        };
        for (f, set) in fingers.iter().enumerate() {
            touching[f] |= set.contains(&hand_geom);
        }
        palm_touches |= palm.contains(&hand_geom);
    }
    let count = |t: &[bool]| t.iter().filter(|x| **x).count() as u32;
    let all = count(&touching);
    let value = if opposed {
        let (others, thumb) = touching.split_at(touching.len().saturating_sub(1));
        (thumb.iter().any(|t| *t) || palm_touches) && count(others) >= min_fingers
    } else {
        all >= min_fingers
    };
    (value, vec![f64::from(all)])
}

/// g_pose, g_joint and g_contact nodes: a value read off the simulation.
fn eval_sensing<M: ModelType>(node: &mut Compiled, data: &MjData<M>) -> bool {
    match node {
        Compiled::Cylinder {
            point,
            center,
            axis,
            radius,
            along,
        } => p::in_cylinder(
            read_point(data, *point),
            read_point(data, *center),
            *axis,
            *radius,
            *along,
        ),
        Compiled::Box {
            point,
            origin,
            axes,
            min,
            max,
        } => {
            let (o, m) = read_frame(data, *origin);
            let pt = read_point(data, *point);
            let d = [pt[0] - o[0], pt[1] - o[1], pt[2] - o[2]];
            let d = match axes {
                BoxAxes::World => d,
                BoxAxes::Origin => p::to_local(&m, d),
            };
            p::in_box(d, *min, *max)
        }
        Compiled::SiteSpan { point, sites } => {
            let corners: Vec<[f64; 3]> = sites.iter().map(|s| data.site_xpos()[*s]).collect();
            p::in_span(read_point(data, *point), &corners)
        }
        Compiled::Rise {
            sites,
            min_rise,
            z0,
        } => sites
            .iter()
            .zip(z0.iter())
            .all(|(s, z)| data.site_xpos()[*s][2] - z >= *min_rise),
        Compiled::Above {
            point,
            reference,
            min_offset,
            at_reset,
            ref_z,
        } => {
            let r = if *at_reset {
                *ref_z
            } else {
                read_point(data, *reference)[2]
            };
            read_point(data, *point)[2] >= r + *min_offset
        }
        Compiled::Align {
            frame,
            axis,
            target,
            max_angle_deg,
        } => {
            let (_, m) = read_frame(data, *frame);
            p::axis_angle_deg(&m, *axis, *target) <= *max_angle_deg
        }
        Compiled::JointCmp { joint, op, value } => {
            p::compare(*op, read_joint(data, *joint), *value)
        }
        Compiled::JointRise {
            joint,
            delta,
            at_reset,
        } => read_joint(data, *joint) - *at_reset > *delta,
        Compiled::JointLatch {
            joint,
            set,
            clear,
            state,
            ..
        } => p::hysteresis(state, read_joint(data, *joint), set, clear),
        Compiled::Contact {
            a,
            b: bset,
            max_dist,
        } => data.contact().iter().any(|c| {
            let (g1, g2) = (c.geom[0] as usize, c.geom[1] as usize);
            max_dist.is_none_or(|m| c.dist <= m)
                && ((a.contains(g1) && bset.contains(g2)) || (a.contains(g2) && bset.contains(g1)))
        }),
        _ => unreachable!("not a sensing node"),
    }
}

/// g_seq nodes: logic over their inputs' values of this step.
fn eval_logic(node: &mut Compiled, inputs: &[bool], number: f64) -> (bool, Vec<f64>) {
    let b = |x: bool| f64::from(u8::from(x));
    match node {
        Compiled::All(_) => (inputs.iter().all(|x| *x), vec![]),
        Compiled::Any(_) => (inputs.iter().any(|x| *x), vec![]),
        Compiled::Not(_) => (!inputs[0], vec![]),
        Compiled::Held { steps, hold, .. } => {
            let v = hold.update(inputs[0], *steps);
            (v, vec![f64::from(hold.count)])
        }
        Compiled::Rising { edge, .. } => (edge.rising(inputs[0]), vec![]),
        Compiled::Falling { edge, .. } => (edge.falling(inputs[0]), vec![]),
        Compiled::Counter {
            at_least, count, ..
        } => {
            let v = count.update(inputs[0], *at_least);
            (v, vec![f64::from(count.count)])
        }
        Compiled::Latch { state, .. } => (p::latch(state, inputs[0], inputs[1]), vec![]),
        Compiled::Seq { seq, .. } => {
            let v = seq.update(inputs);
            (v, vec![seq.index as f64, b(seq.wrong)])
        }
        Compiled::ValueCmp { op, value, .. } => (p::compare(*op, number, *value), vec![]),
        _ => unreachable!("not a logic node"),
    }
}

/// Scene mechanics (the nail, the keypad, the Hanoi stacks), which may move a mocap body.
fn eval_mechanic<M: ModelType>(node: &mut Compiled, data: &mut MjData<M>) -> (bool, Vec<f64>) {
    let b = |x: bool| f64::from(u8::from(x));
    match node {
        Compiled::Nail {
            hammer,
            nail,
            mocap,
            params,
            state,
            z0,
            ..
        } => {
            let touching = data.contact().iter().any(|c| {
                let (g1, g2) = (c.geom[0] as usize, c.geom[1] as usize);
                (hammer.contains(&g1) && nail.contains(&g2))
                    || (hammer.contains(&g2) && nail.contains(&g1))
            });
            let grew = state.strike(touching, params);
            if grew {
                data.mocap_pos_mut()[*mocap][2] = *z0 - state.depth;
                forward(data);
            }
            (grew, vec![state.depth])
        }
        Compiled::Keypad {
            buttons,
            fingers,
            password,
            state,
        } => {
            let pressed: BTreeSet<usize> = if state.unlocked {
                BTreeSet::new()
            } else {
                buttons
                    .iter()
                    .enumerate()
                    .filter(|(_, (g, _))| {
                        data.contact().iter().any(|c| {
                            let (g1, g2) = (c.geom[0] as usize, c.geom[1] as usize);
                            (g1 == *g && fingers.contains(&g2))
                                || (g2 == *g && fingers.contains(&g1))
                        })
                    })
                    .map(|(k, _)| k)
                    .collect()
            };
            let digits: Vec<u8> = buttons.iter().map(|(_, d)| *d).collect();
            let v = state.update(&pressed, |k| digits[k], password);
            (v, vec![b(state.failed), state.index as f64])
        }
        Compiled::Hanoi {
            base,
            posts,
            disks,
            params,
            state,
        } => {
            let qpos = data.qpos();
            let qvel = data.qvel();
            let ds: Vec<DiskState> = disks
                .iter()
                .map(|(q, v)| DiskState {
                    pos: [qpos[*q], qpos[q + 1], qpos[q + 2]],
                    speed: qvel[*v..v + 6].iter().map(|x| x * x).sum::<f64>().sqrt(),
                })
                .collect();
            let ps: Vec<[f64; 3]> = posts.iter().map(|s| data.site_xpos()[*s]).collect();
            let v = state.update(&ds, &ps, data.xpos()[*base][2], params);
            (v, vec![b(state.illegal), state.on_goal as f64])
        }
        _ => unreachable!("not a mechanic node"),
    }
}

fn sensor3(sensordata: &[f64], adr: usize) -> [f64; 3] {
    [sensordata[adr], sensordata[adr + 1], sensordata[adr + 2]]
}

pub(super) fn read_point<M: ModelType>(data: &MjData<M>, p: Point) -> [f64; 3] {
    match p {
        Point::Sensor(adr) => sensor3(data.sensordata(), adr),
        Point::Site(i) => data.site_xpos()[i],
        Point::Body(i) => data.xpos()[i],
        Point::Geom(i) => data.geom_xpos()[i],
    }
}

fn read_frame<M: ModelType>(data: &MjData<M>, f: Frame) -> ([f64; 3], [f64; 9]) {
    match f {
        Frame::Site(i) => (data.site_xpos()[i], data.site_xmat()[i]),
        Frame::Body(i) => (data.xpos()[i], data.xmat()[i]),
        Frame::Geom(i) => (data.geom_xpos()[i], data.geom_xmat()[i]),
    }
}

pub(super) fn read_joint<M: ModelType>(data: &MjData<M>, j: Joint) -> f64 {
    match j {
        Joint::Sensor(adr) => data.sensordata()[adr],
        Joint::Qpos(adr) => data.qpos()[adr],
    }
}

/// `mj_forward` on the data's own model.
fn forward<M: ModelType>(data: &mut MjData<M>) {
    data.forward();
}
