//! Evaluates a task spec's condition graph on the simulation after every control step.

use std::collections::BTreeSet;

use dexjoco_core::{
    Axis, BoxAxes, Cmp, FrameRef, GeomSet, JointRef, NameKind, Node, PointRef, TaskSpec, Threshold,
};
use mujoco_rs::prelude::{MjData, MjModel, MjtObjBase};
use mujoco_rs::wrappers::mj_model::traits::ModelType;

use crate::error::SimError;
use crate::primitives::{
    self as p, Count, DiskState, Edge, Hanoi, HanoiParams, Hold, Keypad, Nail, NailParams, Sequence,
};

/// The id of a named object of a model, or `None`.
pub fn name_id(model: &MjModel, kind: NameKind, name: &str) -> Option<usize> {
    let t = match kind {
        NameKind::Joint => MjtObjBase::mjOBJ_JOINT,
        NameKind::Body => MjtObjBase::mjOBJ_BODY,
        NameKind::Site => MjtObjBase::mjOBJ_SITE,
        NameKind::Geom => MjtObjBase::mjOBJ_GEOM,
        NameKind::Camera => MjtObjBase::mjOBJ_CAMERA,
        NameKind::Sensor => MjtObjBase::mjOBJ_SENSOR,
        NameKind::Actuator => MjtObjBase::mjOBJ_ACTUATOR,
    };
    model.name_to_id(t, name)
}

/// Every name a spec refers to that the model lacks, as `kind 'name'`.
pub fn unresolved_names(spec: &TaskSpec, model: &MjModel) -> Vec<String> {
    spec.scene_names()
        .into_iter()
        .filter(|(k, n)| name_id(model, *k, n).is_none())
        .map(|(k, n)| format!("{} '{n}'", k.as_str()))
        .collect()
}

/// Resolves names, collecting every missing one.
pub(crate) struct Resolver<'a> {
    model: &'a MjModel,
    missing: Vec<String>,
}

impl<'a> Resolver<'a> {
    pub(crate) fn new(model: &'a MjModel) -> Self {
        Self {
            model,
            missing: Vec::new(),
        }
    }

    pub(crate) fn id(&mut self, kind: NameKind, name: &str) -> usize {
        name_id(self.model, kind, name).unwrap_or_else(|| {
            self.missing.push(format!("{} '{name}'", kind.as_str()));
            usize::MAX
        })
    }

    pub(crate) fn finish(self, what: &str) -> Result<(), SimError> {
        if self.missing.is_empty() {
            Ok(())
        } else {
            Err(SimError::MissingNames {
                what: what.into(),
                names: self.missing,
            })
        }
    }
}

#[derive(Debug, Clone, Copy)]
enum Point {
    Sensor(usize),
    Site(usize),
    Body(usize),
    Geom(usize),
}

#[derive(Debug, Clone, Copy)]
enum Frame {
    Site(usize),
    Body(usize),
    Geom(usize),
}

#[derive(Debug, Clone, Copy)]
enum Joint {
    Sensor(usize),
    Qpos(usize),
}

#[derive(Debug, Clone)]
enum Geoms {
    Any,
    Set(BTreeSet<usize>),
    Outside(BTreeSet<usize>),
}

impl Geoms {
    fn contains(&self, g: usize) -> bool {
        match self {
            Self::Any => true,
            Self::Set(s) => s.contains(&g),
            Self::Outside(s) => !s.contains(&g),
        }
    }
}

/// A reference to a node's value (`port == None`) or one of its outputs.
#[derive(Debug, Clone, Copy)]
struct Port {
    node: usize,
    output: Option<usize>,
}

#[derive(Debug, Clone)]
enum Compiled {
    Cylinder {
        point: Point,
        center: Point,
        axis: Axis,
        radius: f64,
        along: [f64; 2],
    },
    Box {
        point: Point,
        origin: Frame,
        axes: BoxAxes,
        min: [f64; 3],
        max: [f64; 3],
    },
    SiteSpan {
        point: Point,
        sites: Vec<usize>,
    },
    Rise {
        sites: Vec<usize>,
        min_rise: f64,
        z0: Vec<f64>,
    },
    Above {
        point: Point,
        reference: Point,
        min_offset: f64,
        at_reset: bool,
        ref_z: f64,
    },
    Align {
        frame: Frame,
        axis: Axis,
        target: [f64; 3],
        max_angle_deg: f64,
    },
    JointCmp {
        joint: Joint,
        op: Cmp,
        value: f64,
    },
    JointRise {
        joint: Joint,
        delta: f64,
        at_reset: f64,
    },
    JointLatch {
        joint: Joint,
        set: Threshold,
        clear: Threshold,
        initial: bool,
        state: bool,
    },
    Contact {
        a: Geoms,
        b: Geoms,
        max_dist: Option<f64>,
    },
    All(Vec<Port>),
    Any(Vec<Port>),
    Not(Port),
    Held {
        of: Port,
        steps: u32,
        hold: Hold,
    },
    Rising {
        of: Port,
        edge: Edge,
    },
    Falling {
        of: Port,
        edge: Edge,
    },
    Counter {
        of: Port,
        at_least: u32,
        count: Count,
    },
    Latch {
        set: Port,
        clear: Option<Port>,
        state: bool,
    },
    Seq {
        events: Vec<Port>,
        seq: Sequence,
    },
    ValueCmp {
        of: Port,
        op: Cmp,
        value: f64,
    },
    Nail {
        hammer: BTreeSet<usize>,
        nail: BTreeSet<usize>,
        face: usize,
        mocap: usize,
        params: NailParams,
        state: Nail,
        z0: f64,
    },
    Keypad {
        buttons: Vec<(usize, u8)>,
        fingers: BTreeSet<usize>,
        password: Vec<u8>,
        state: Keypad,
    },
    Hanoi {
        base: usize,
        posts: Vec<usize>,
        disks: Vec<(usize, usize)>,
        params: HanoiParams,
        state: Hanoi,
    },
}

/// What the checker says after a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Verdict {
    /// The task's success condition holds on this step.
    pub success: bool,
    /// The task's failure condition holds (the episode ends as a failure).
    pub failure: bool,
}

/// Evaluates a [`TaskSpec`]'s conditions on an `MjData` after every control step.
///
/// Call [`reset`](Self::reset) after the environment's reset or restore (it reads the
/// reset-time values: joint rest values, site heights, the nail height),
/// [`after_substep`](Self::after_substep) after each physics substep, and
/// [`after_step`](Self::after_step) after the substeps of a control step.
#[derive(Debug, Clone)]
pub struct SuccessChecker {
    names: Vec<String>,
    nodes: Vec<Compiled>,
    values: Vec<bool>,
    outputs: Vec<Vec<f64>>,
    success: Port,
    failure: Option<Port>,
}

fn sensor3(sensordata: &[f64], adr: usize) -> [f64; 3] {
    [sensordata[adr], sensordata[adr + 1], sensordata[adr + 2]]
}

impl SuccessChecker {
    /// Compiles a spec for a model; every missing scene name is listed in the error.
    pub fn new(spec: &TaskSpec, model: &MjModel) -> Result<Self, SimError> {
        let order = spec
            .evaluation_order()
            .map_err(|e| SimError::Spec(e.to_string()))?;
        let index = |name: &str| order.iter().position(|n| n == name);
        let port = |r: &str| -> Result<Port, SimError> {
            let (base, out) = match r.split_once('.') {
                Some((b, o)) => (b, Some(o)),
                None => (r, None),
            };
            let node =
                index(base).ok_or_else(|| SimError::Spec(format!("unknown node '{base}'")))?;
            let output = match out {
                None => None,
                Some(o) => Some(
                    spec.nodes[base]
                        .outputs()
                        .iter()
                        .position(|x| *x == o)
                        .ok_or_else(|| SimError::Spec(format!("no output '{r}'")))?,
                ),
            };
            Ok(Port { node, output })
        };
        let mut res = Resolver::new(model);
        let mut nodes = Vec::new();
        let sensor_adr = model.sensor_adr();
        let qpos_adr = model.jnt_qposadr();
        for name in &order {
            let node = &spec.nodes[name];
            let point = |r: &mut Resolver, p: &PointRef| match p {
                PointRef::Sensor(n) => {
                    let id = r.id(NameKind::Sensor, n);
                    Point::Sensor(sensor_adr.get(id).map_or(0, |a| *a as usize))
                }
                PointRef::Site(n) => Point::Site(r.id(NameKind::Site, n)),
                PointRef::Body(n) => Point::Body(r.id(NameKind::Body, n)),
                PointRef::Geom(n) => Point::Geom(r.id(NameKind::Geom, n)),
            };
            let frame = |r: &mut Resolver, f: &FrameRef| match f {
                FrameRef::Site(n) => Frame::Site(r.id(NameKind::Site, n)),
                FrameRef::Body(n) => Frame::Body(r.id(NameKind::Body, n)),
                FrameRef::Geom(n) => Frame::Geom(r.id(NameKind::Geom, n)),
            };
            let joint = |r: &mut Resolver, j: &JointRef| match j {
                JointRef::Sensor(n) => {
                    let id = r.id(NameKind::Sensor, n);
                    Joint::Sensor(sensor_adr.get(id).map_or(0, |a| *a as usize))
                }
                JointRef::Qpos(n) => {
                    let id = r.id(NameKind::Joint, n);
                    Joint::Qpos(qpos_adr.get(id).map_or(0, |a| *a as usize))
                }
            };
            let geoms = |r: &mut Resolver, g: &GeomSet| match g {
                GeomSet::Any => Geoms::Any,
                GeomSet::Geoms(v) => {
                    Geoms::Set(v.iter().map(|n| r.id(NameKind::Geom, n)).collect())
                }
                GeomSet::Subtree(b) => Geoms::Set(subtree_geoms(model, r.id(NameKind::Body, b))),
                GeomSet::OutsideSubtree(b) => {
                    Geoms::Outside(subtree_geoms(model, r.id(NameKind::Body, b)))
                }
            };
            let set = |r: &mut Resolver, v: &[String]| -> BTreeSet<usize> {
                v.iter().map(|n| r.id(NameKind::Geom, n)).collect()
            };
            let c = match node {
                Node::PointInCylinder {
                    point: pt,
                    center,
                    axis,
                    radius,
                    along,
                } => Compiled::Cylinder {
                    point: point(&mut res, pt),
                    center: point(&mut res, center),
                    axis: *axis,
                    radius: *radius,
                    along: *along,
                },
                Node::PointInBox {
                    point: pt,
                    origin,
                    axes,
                    min,
                    max,
                } => Compiled::Box {
                    point: point(&mut res, pt),
                    origin: frame(&mut res, origin),
                    axes: *axes,
                    min: *min,
                    max: *max,
                },
                Node::PointInSiteBox { point: pt, sites } => Compiled::SiteSpan {
                    point: point(&mut res, pt),
                    sites: sites.iter().map(|s| res.id(NameKind::Site, s)).collect(),
                },
                Node::HeightAboveReset { sites, min_rise } => Compiled::Rise {
                    sites: sites.iter().map(|s| res.id(NameKind::Site, s)).collect(),
                    min_rise: *min_rise,
                    z0: vec![0.0; sites.len()],
                },
                Node::AboveReference {
                    point: pt,
                    reference,
                    min_offset,
                    reference_at_reset,
                } => Compiled::Above {
                    point: point(&mut res, pt),
                    reference: point(&mut res, reference),
                    min_offset: *min_offset,
                    at_reset: *reference_at_reset,
                    ref_z: 0.0,
                },
                Node::AxisAlignment {
                    frame: f,
                    axis,
                    target,
                    max_angle_deg,
                } => Compiled::Align {
                    frame: frame(&mut res, f),
                    axis: *axis,
                    target: *target,
                    max_angle_deg: *max_angle_deg,
                },
                Node::JointThreshold {
                    joint: j,
                    op,
                    value,
                } => Compiled::JointCmp {
                    joint: joint(&mut res, j),
                    op: *op,
                    value: *value,
                },
                Node::JointAboveReset { joint: j, delta } => Compiled::JointRise {
                    joint: joint(&mut res, j),
                    delta: *delta,
                    at_reset: 0.0,
                },
                Node::JointHysteresis {
                    joint: j,
                    set,
                    clear,
                    initial,
                } => Compiled::JointLatch {
                    joint: joint(&mut res, j),
                    set: *set,
                    clear: *clear,
                    initial: *initial,
                    state: *initial,
                },
                Node::Contact { a, b, max_dist } => Compiled::Contact {
                    a: geoms(&mut res, a),
                    b: geoms(&mut res, b),
                    max_dist: *max_dist,
                },
                Node::All { of } => {
                    Compiled::All(of.iter().map(|r| port(r)).collect::<Result<_, _>>()?)
                }
                Node::Any { of } => {
                    Compiled::Any(of.iter().map(|r| port(r)).collect::<Result<_, _>>()?)
                }
                Node::Not { of } => Compiled::Not(port(of)?),
                Node::Held { of, steps } => Compiled::Held {
                    of: port(of)?,
                    steps: *steps,
                    hold: Hold::default(),
                },
                Node::RisingEdge { of } => Compiled::Rising {
                    of: port(of)?,
                    edge: Edge::default(),
                },
                Node::FallingEdge { of } => Compiled::Falling {
                    of: port(of)?,
                    edge: Edge::default(),
                },
                Node::Counter { of, at_least } => Compiled::Counter {
                    of: port(of)?,
                    at_least: *at_least,
                    count: Count::default(),
                },
                Node::Latch { set, clear } => Compiled::Latch {
                    set: port(set)?,
                    clear: clear.as_deref().map(port).transpose()?,
                    state: false,
                },
                Node::Sequence { events } => Compiled::Seq {
                    events: events.iter().map(|r| port(r)).collect::<Result<_, _>>()?,
                    seq: Sequence::default(),
                },
                Node::ValueThreshold { of, op, value } => Compiled::ValueCmp {
                    of: port(of)?,
                    op: *op,
                    value: *value,
                },
                Node::NailSinking {
                    hammer,
                    nail,
                    face,
                    nail_body,
                    window,
                    vz_divisor,
                    min_vz,
                    gain,
                    max_scale,
                    max_depth,
                } => {
                    let body = res.id(NameKind::Body, nail_body);
                    let mocap = model.body_mocapid().get(body).copied().unwrap_or(-1);
                    if body != usize::MAX && mocap < 0 {
                        return Err(SimError::Spec(format!(
                            "body '{nail_body}' is not a mocap body"
                        )));
                    }
                    Compiled::Nail {
                        hammer: set(&mut res, hammer),
                        nail: set(&mut res, nail),
                        face: res.id(NameKind::Geom, face),
                        mocap: mocap.max(0) as usize,
                        params: NailParams {
                            window: *window,
                            vz_divisor: *vz_divisor,
                            min_vz: *min_vz,
                            gain: *gain,
                            max_scale: *max_scale,
                            max_depth: *max_depth,
                        },
                        state: Nail::default(),
                        z0: 0.0,
                    }
                }
                Node::Keypad {
                    buttons,
                    fingers,
                    password,
                } => {
                    let mut b: Vec<(usize, u8)> = buttons
                        .iter()
                        .map(|b| (res.id(NameKind::Geom, &b.geom), b.digit))
                        .collect();
                    // New presses are handled in ascending geom id order.
                    b.sort();
                    Compiled::Keypad {
                        buttons: b,
                        fingers: set(&mut res, fingers),
                        password: password.clone(),
                        state: Keypad::default(),
                    }
                }
                Node::HanoiTowers {
                    base,
                    posts,
                    disks,
                    top_offset,
                    half_height,
                    static_speed,
                    post_radius,
                    table_margin,
                    xy_tol,
                    z_tol,
                    goal_post,
                    illegal_steps,
                } => Compiled::Hanoi {
                    base: res.id(NameKind::Body, base),
                    posts: posts.iter().map(|s| res.id(NameKind::Site, s)).collect(),
                    disks: disks
                        .iter()
                        .map(|d| {
                            let j = res.id(NameKind::Joint, &d.joint);
                            let q = qpos_adr.get(j).map_or(0, |a| *a as usize);
                            let v = model.jnt_dofadr().get(j).map_or(0, |a| *a as usize);
                            (q, v)
                        })
                        .collect(),
                    params: HanoiParams {
                        top_offset: *top_offset,
                        half_height: *half_height,
                        static_speed: *static_speed,
                        post_radius: *post_radius,
                        table_margin: *table_margin,
                        xy_tol: *xy_tol,
                        z_tol: *z_tol,
                        goal_post: *goal_post,
                        illegal_steps: *illegal_steps,
                    },
                    state: Hanoi::default(),
                },
            };
            nodes.push(c);
        }
        res.finish(&format!("task '{}'", spec.id))?;
        let n = nodes.len();
        let success = port(&spec.success)?;
        let failure = spec.failure.as_deref().map(port).transpose()?;
        Ok(Self {
            outputs: order
                .iter()
                .map(|name| vec![0.0; spec.nodes[name].outputs().len()])
                .collect(),
            names: order,
            nodes,
            values: vec![false; n],
            success,
            failure,
        })
    }

    /// Node names in evaluation order.
    pub fn node_names(&self) -> &[String] {
        &self.names
    }

    /// A node's value on the last step.
    pub fn value(&self, node: &str) -> Option<bool> {
        self.names
            .iter()
            .position(|n| n == node)
            .map(|i| self.values[i])
    }

    /// A node's named output on the last step (booleans as 0 / 1).
    pub fn output(&self, node: &str, output: &str) -> Option<f64> {
        let i = self.names.iter().position(|n| n == node)?;
        let names = output_names(&self.nodes[i]);
        let k = names.iter().position(|o| *o == output)?;
        Some(self.outputs[i][k])
    }

    /// Reads the reset-time values and clears every counter and latch.
    pub fn reset<M: ModelType>(&mut self, data: &MjData<M>) {
        for (i, node) in self.nodes.iter_mut().enumerate() {
            self.values[i] = false;
            self.outputs[i].iter_mut().for_each(|v| *v = 0.0);
            match node {
                Compiled::Rise { sites, z0, .. } => {
                    for (z, s) in z0.iter_mut().zip(sites.iter()) {
                        *z = data.site_xpos()[*s][2];
                    }
                }
                Compiled::Above {
                    reference, ref_z, ..
                } => *ref_z = read_point(data, *reference)[2],
                Compiled::JointRise {
                    joint, at_reset, ..
                } => *at_reset = read_joint(data, *joint),
                Compiled::JointLatch { initial, state, .. } => *state = *initial,
                Compiled::Held { hold, .. } => *hold = Hold::default(),
                Compiled::Rising { edge, .. } | Compiled::Falling { edge, .. } => {
                    *edge = Edge::default()
                }
                Compiled::Counter { count, .. } => *count = Count::default(),
                Compiled::Latch { state, .. } => *state = false,
                Compiled::Seq { seq, .. } => *seq = Sequence::default(),
                Compiled::Nail {
                    face,
                    mocap,
                    state,
                    z0,
                    ..
                } => {
                    state.reset(data.geom_xpos()[*face][2]);
                    *z0 = data.mocap_pos()[*mocap][2];
                }
                Compiled::Keypad { state, .. } => *state = Keypad::default(),
                Compiled::Hanoi { state, .. } => *state = Hanoi::default(),
                _ => {}
            }
        }
    }

    /// Bookkeeping after each physics substep (the nail's face speed window).
    pub fn after_substep<M: ModelType>(&mut self, data: &MjData<M>) {
        for node in &mut self.nodes {
            if let Compiled::Nail {
                face,
                params,
                state,
                ..
            } = node
            {
                state.sample(data.geom_xpos()[*face][2], params);
            }
        }
    }

    /// After the substeps of a control step: runs the scene mechanics (which may move
    /// a mocap body and call `mj_forward`, as the reference does), then evaluates every
    /// node in dependency order.
    pub fn after_step<M: ModelType>(&mut self, data: &mut MjData<M>) -> Verdict {
        for i in 0..self.nodes.len() {
            let (value, outs) = self.eval(i, data);
            self.values[i] = value;
            for (k, v) in outs.into_iter().enumerate() {
                self.outputs[i][k] = v;
            }
        }
        Verdict {
            success: self.read(self.success),
            failure: self.failure.is_some_and(|f| self.read(f)),
        }
    }

    fn read(&self, p: Port) -> bool {
        match p.output {
            None => self.values[p.node],
            Some(k) => self.outputs[p.node][k] != 0.0,
        }
    }

    fn num(&self, p: Port) -> f64 {
        match p.output {
            None => f64::from(u8::from(self.values[p.node])),
            Some(k) => self.outputs[p.node][k],
        }
    }

    fn eval<M: ModelType>(&mut self, i: usize, data: &mut MjData<M>) -> (bool, Vec<f64>) {
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
        let b = |x: bool| f64::from(u8::from(x));
        match &mut self.nodes[i] {
            Compiled::Cylinder {
                point,
                center,
                axis,
                radius,
                along,
            } => {
                let v = p::in_cylinder(
                    read_point(data, *point),
                    read_point(data, *center),
                    *axis,
                    *radius,
                    *along,
                );
                (v, vec![])
            }
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
                (p::in_box(d, *min, *max), vec![])
            }
            Compiled::SiteSpan { point, sites } => {
                let corners: Vec<[f64; 3]> = sites.iter().map(|s| data.site_xpos()[*s]).collect();
                (p::in_span(read_point(data, *point), &corners), vec![])
            }
            Compiled::Rise {
                sites,
                min_rise,
                z0,
            } => {
                let v = sites
                    .iter()
                    .zip(z0.iter())
                    .all(|(s, z)| data.site_xpos()[*s][2] - z >= *min_rise);
                (v, vec![])
            }
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
                (read_point(data, *point)[2] >= r + *min_offset, vec![])
            }
            Compiled::Align {
                frame,
                axis,
                target,
                max_angle_deg,
            } => {
                let (_, m) = read_frame(data, *frame);
                (
                    p::axis_angle_deg(&m, *axis, *target) <= *max_angle_deg,
                    vec![],
                )
            }
            Compiled::JointCmp { joint, op, value } => {
                (p::compare(*op, read_joint(data, *joint), *value), vec![])
            }
            Compiled::JointRise {
                joint,
                delta,
                at_reset,
            } => (read_joint(data, *joint) - *at_reset > *delta, vec![]),
            Compiled::JointLatch {
                joint,
                set,
                clear,
                state,
                ..
            } => (
                p::hysteresis(state, read_joint(data, *joint), set, clear),
                vec![],
            ),
            Compiled::Contact {
                a,
                b: bset,
                max_dist,
            } => {
                let v = data.contact().iter().any(|c| {
                    let (g1, g2) = (c.geom[0] as usize, c.geom[1] as usize);
                    max_dist.is_none_or(|m| c.dist <= m)
                        && ((a.contains(g1) && bset.contains(g2))
                            || (a.contains(g2) && bset.contains(g1)))
                });
                (v, vec![])
            }
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
                let v = seq.update(&inputs);
                (v, vec![seq.index as f64, b(seq.wrong)])
            }
            Compiled::ValueCmp { op, value, .. } => (p::compare(*op, number, *value), vec![]),
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
                (v, vec![b(state.illegal)])
            }
        }
    }
}

fn output_names(c: &Compiled) -> &'static [&'static str] {
    match c {
        Compiled::Held { .. } | Compiled::Counter { .. } => &["count"],
        Compiled::Seq { .. } => &["index", "wrong"],
        Compiled::Nail { .. } => &["depth"],
        Compiled::Keypad { .. } => &["failed", "index"],
        Compiled::Hanoi { .. } => &["illegal"],
        _ => &[],
    }
}

fn read_point<M: ModelType>(data: &MjData<M>, p: Point) -> [f64; 3] {
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

fn read_joint<M: ModelType>(data: &MjData<M>, j: Joint) -> f64 {
    match j {
        Joint::Sensor(adr) => data.sensordata()[adr],
        Joint::Qpos(adr) => data.qpos()[adr],
    }
}

/// Geoms of a body and its descendants.
fn subtree_geoms(model: &MjModel, body: usize) -> BTreeSet<usize> {
    if body == usize::MAX {
        return BTreeSet::new();
    }
    let parent = model.body_parentid();
    let in_subtree = |mut b: usize| loop {
        if b == body {
            return true;
        }
        if b == 0 {
            return false;
        }
        b = parent[b] as usize;
    };
    model
        .geom_bodyid()
        .iter()
        .enumerate()
        .filter(|(_, b)| in_subtree(**b as usize))
        .map(|(g, _)| g)
        .collect()
}

/// `mj_forward` on the data's own model.
pub(crate) fn forward<M: ModelType>(data: &mut MjData<M>) {
    data.forward();
}
