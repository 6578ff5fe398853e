//! Compiling a task spec's condition graph for one model: every name resolved to an id
//! (all missing ones listed at once), every node turned into a [`Compiled`] node with its
//! state, in evaluation order.

use std::collections::BTreeSet;

use dexjoco_core::{
    Axis, BoxAxes, Cmp, FrameRef, GeomSet, HanoiDisk, JointRef, KeypadButton, NameKind, Node,
    PointRef, TaskSpec, Threshold,
};
use mujoco_rs::prelude::MjModel;

use super::name_id;
use crate::error::SimError;
use crate::primitives::{
    Count, Edge, Hanoi, HanoiParams, Hold, Keypad, Nail, NailParams, Sequence,
};

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
pub(super) enum Point {
    Sensor(usize),
    Site(usize),
    Body(usize),
    Geom(usize),
}

#[derive(Debug, Clone, Copy)]
pub(super) enum Frame {
    Site(usize),
    Body(usize),
    Geom(usize),
}

#[derive(Debug, Clone, Copy)]
pub(super) enum Joint {
    Sensor(usize),
    Qpos(usize),
}

#[derive(Debug, Clone)]
pub(super) enum Geoms {
    Any,
    Set(BTreeSet<usize>),
    Outside(BTreeSet<usize>),
}

impl Geoms {
    pub(super) fn contains(&self, g: usize) -> bool {
        match self {
            Self::Any => true,
            Self::Set(s) => s.contains(&g),
            Self::Outside(s) => !s.contains(&g),
        }
    }
}

/// A reference to a node's value (`port == None`) or one of its outputs.
#[derive(Debug, Clone, Copy)]
pub(super) struct Port {
    pub(super) node: usize,
    pub(super) output: Option<usize>,
}

#[derive(Debug, Clone)]
pub(super) enum Compiled {
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
    /// The geoms of each finger (thumb last), of the palm and of the object.
    Grasp {
        fingers: Vec<BTreeSet<usize>>,
        palm: BTreeSet<usize>,
        object: Geoms,
        min_fingers: u32,
        opposed: bool,
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

/// A compiled graph: node names and nodes in evaluation order, the success and failure
/// ports.
pub(super) struct Graph {
    pub(super) names: Vec<String>,
    pub(super) nodes: Vec<Compiled>,
    pub(super) success: Port,
    pub(super) failure: Option<Port>,
}

/// Compiles `spec` for `model`; every missing scene name is listed in the error.
pub(super) fn compile(spec: &TaskSpec, model: &MjModel) -> Result<Graph, SimError> {
    let order = spec
        .evaluation_order()
        .map_err(|e| SimError::Spec(Box::new(e)))?;
    let mut c = Compiler {
        spec,
        model,
        order: &order,
        res: Resolver::new(model),
    };
    let mut nodes = Vec::with_capacity(order.len());
    for name in &order {
        nodes.push(c.node(&spec.nodes[name])?);
    }
    let success = c.port(&spec.success)?;
    let failure = spec.failure.as_deref().map(|f| c.port(f)).transpose()?;
    c.res.finish(&format!("task '{}'", spec.id))?;
    Ok(Graph {
        names: order.clone(),
        nodes,
        success,
        failure,
    })
}

/// Turns spec nodes into compiled ones, resolving names as it goes.
struct Compiler<'a> {
    spec: &'a TaskSpec,
    model: &'a MjModel,
    order: &'a [String],
    res: Resolver<'a>,
}

impl Compiler<'_> {
    /// A node's value (`name`) or named output (`name.output`).
    fn port(&self, r: &str) -> Result<Port, SimError> {
        let (base, out) = match r.split_once('.') {
            Some((b, o)) => (b, Some(o)),
            None => (r, None),
        };
        let node = self
            .order
            .iter()
            .position(|n| n == base)
            .ok_or_else(|| SimError::UnknownNode(base.into()))?;
        let output = match out {
            None => None,
            Some(o) => Some(
                self.spec.nodes[base]
                    .outputs()
                    .iter()
                    .position(|x| *x == o)
                    .ok_or_else(|| SimError::UnknownOutput(r.into()))?,
            ),
        };
        Ok(Port { node, output })
    }

    fn ports(&self, refs: &[String]) -> Result<Vec<Port>, SimError> {
        refs.iter().map(|r| self.port(r)).collect()
    }

    fn sensor_adr(&mut self, name: &str) -> usize {
        let id = self.res.id(NameKind::Sensor, name);
        self.model.sensor_adr().get(id).map_or(0, |a| *a as usize)
    }

    fn point(&mut self, p: &PointRef) -> Point {
        match p {
            PointRef::Sensor(n) => Point::Sensor(self.sensor_adr(n)),
            PointRef::Site(n) => Point::Site(self.res.id(NameKind::Site, n)),
            PointRef::Body(n) => Point::Body(self.res.id(NameKind::Body, n)),
            PointRef::Geom(n) => Point::Geom(self.res.id(NameKind::Geom, n)),
        }
    }

    fn frame(&mut self, f: &FrameRef) -> Frame {
        match f {
            FrameRef::Site(n) => Frame::Site(self.res.id(NameKind::Site, n)),
            FrameRef::Body(n) => Frame::Body(self.res.id(NameKind::Body, n)),
            FrameRef::Geom(n) => Frame::Geom(self.res.id(NameKind::Geom, n)),
        }
    }

    fn joint(&mut self, j: &JointRef) -> Joint {
        match j {
            JointRef::Sensor(n) => Joint::Sensor(self.sensor_adr(n)),
            JointRef::Qpos(n) => {
                let id = self.res.id(NameKind::Joint, n);
                Joint::Qpos(self.model.jnt_qposadr().get(id).map_or(0, |a| *a as usize))
            }
        }
    }

    fn geoms(&mut self, g: &GeomSet) -> Geoms {
        match g {
            GeomSet::Any => Geoms::Any,
            GeomSet::Geoms(v) => Geoms::Set(self.set(v)),
            GeomSet::Subtree(b) => {
                let body = self.res.id(NameKind::Body, b);
                Geoms::Set(subtree_geoms(self.model, body))
            }
            GeomSet::OutsideSubtree(b) => {
                let body = self.res.id(NameKind::Body, b);
                Geoms::Outside(subtree_geoms(self.model, body))
            }
        }
    }

    fn set(&mut self, v: &[String]) -> BTreeSet<usize> {
        v.iter().map(|n| self.res.id(NameKind::Geom, n)).collect()
    }

    fn sites(&mut self, v: &[String]) -> Vec<usize> {
        v.iter().map(|s| self.res.id(NameKind::Site, s)).collect()
    }

    /// Compiles one node, by constraint kind.
    fn node(&mut self, node: &Node) -> Result<Compiled, SimError> {
        match node {
            Node::PointInCylinder { .. }
            | Node::PointInBox { .. }
            | Node::PointInSiteBox { .. }
            | Node::HeightAboveReset { .. }
            | Node::AboveReference { .. }
            | Node::AxisAlignment { .. } => Ok(self.pose_node(node)),
            Node::JointThreshold { .. }
            | Node::JointAboveReset { .. }
            | Node::JointHysteresis { .. }
            | Node::Contact { .. }
            | Node::Grasp { .. } => Ok(self.joint_or_contact_node(node)),
            Node::All { .. }
            | Node::Any { .. }
            | Node::Not { .. }
            | Node::Held { .. }
            | Node::RisingEdge { .. }
            | Node::FallingEdge { .. }
            | Node::Counter { .. }
            | Node::Latch { .. }
            | Node::Sequence { .. }
            | Node::ValueThreshold { .. } => self.seq_node(node),
            Node::NailSinking { .. } | Node::Keypad { .. } | Node::HanoiTowers { .. } => {
                self.mechanic_node(node)
            }
        }
    }

    /// Compiles a g_pose node.
    fn pose_node(&mut self, node: &Node) -> Compiled {
        match node {
            Node::PointInCylinder {
                point: pt,
                center,
                axis,
                radius,
                along,
            } => Compiled::Cylinder {
                point: self.point(pt),
                center: self.point(center),
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
                point: self.point(pt),
                origin: self.frame(origin),
                axes: *axes,
                min: *min,
                max: *max,
            },
            Node::PointInSiteBox { point: pt, sites } => Compiled::SiteSpan {
                point: self.point(pt),
                sites: self.sites(sites),
            },
            Node::HeightAboveReset { sites, min_rise } => Compiled::Rise {
                sites: self.sites(sites),
                min_rise: *min_rise,
                z0: vec![0.0; sites.len()],
            },
            Node::AboveReference {
                point: pt,
                reference,
                min_offset,
                reference_at_reset,
            } => Compiled::Above {
                point: self.point(pt),
                reference: self.point(reference),
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
                frame: self.frame(f),
                axis: *axis,
                target: *target,
                max_angle_deg: *max_angle_deg,
            },
            _ => unreachable!("node() sends only g_pose nodes here"),
        }
    }

    /// Compiles a g_joint or g_contact node.
    fn joint_or_contact_node(&mut self, node: &Node) -> Compiled {
        match node {
            Node::JointThreshold {
                joint: j,
                op,
                value,
            } => Compiled::JointCmp {
                joint: self.joint(j),
                op: *op,
                value: *value,
            },
            Node::JointAboveReset { joint: j, delta } => Compiled::JointRise {
                joint: self.joint(j),
                delta: *delta,
                at_reset: 0.0,
            },
            Node::JointHysteresis {
                joint: j,
                set,
                clear,
                initial,
            } => Compiled::JointLatch {
                joint: self.joint(j),
                set: *set,
                clear: *clear,
                initial: *initial,
                state: *initial,
            },
            Node::Contact { a, b, max_dist } => Compiled::Contact {
                a: self.geoms(a),
                b: self.geoms(b),
                max_dist: *max_dist,
            },
            Node::Grasp {
                hand,
                object,
                min_fingers,
                opposed,
            } => Compiled::Grasp {
                fingers: hand
                    .fingers()
                    .iter()
                    .map(|b| {
                        let body = self.res.id(NameKind::Body, b);
                        subtree_geoms(self.model, body)
                    })
                    .collect(),
                palm: {
                    let body = self.res.id(NameKind::Body, &hand.palm());
                    (0..self.model.ffi().ngeom as usize)
                        .filter(|&g| self.model.geom_bodyid()[g] as usize == body)
                        .collect()
                },
                object: self.geoms(object),
                min_fingers: *min_fingers,
                opposed: *opposed,
            },
            _ => unreachable!("node() sends only g_joint and g_contact nodes here"),
        }
    }

    /// Compiles a g_seq node (time, order, counting, logic).
    fn seq_node(&mut self, node: &Node) -> Result<Compiled, SimError> {
        Ok(match node {
            Node::All { of } => Compiled::All(self.ports(of)?),
            Node::Any { of } => Compiled::Any(self.ports(of)?),
            Node::Not { of } => Compiled::Not(self.port(of)?),
            Node::Held { of, steps } => Compiled::Held {
                of: self.port(of)?,
                steps: *steps,
                hold: Hold::default(),
            },
            Node::RisingEdge { of } => Compiled::Rising {
                of: self.port(of)?,
                edge: Edge::default(),
            },
            Node::FallingEdge { of } => Compiled::Falling {
                of: self.port(of)?,
                edge: Edge::default(),
            },
            Node::Counter { of, at_least } => Compiled::Counter {
                of: self.port(of)?,
                at_least: *at_least,
                count: Count::default(),
            },
            Node::Latch { set, clear } => Compiled::Latch {
                set: self.port(set)?,
                clear: clear.as_deref().map(|c| self.port(c)).transpose()?,
                state: false,
            },
            Node::Sequence { events } => Compiled::Seq {
                events: self.ports(events)?,
                seq: Sequence::default(),
            },
            Node::ValueThreshold { of, op, value } => Compiled::ValueCmp {
                of: self.port(of)?,
                op: *op,
                value: *value,
            },
            _ => unreachable!("node() sends only g_seq nodes here"),
        })
    }

    /// Compiles a scene mechanic (nail, keypad, Hanoi).
    fn mechanic_node(&mut self, node: &Node) -> Result<Compiled, SimError> {
        Ok(match node {
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
                let mocap = self.nail_mocap(nail_body)?;
                Compiled::Nail {
                    hammer: self.set(hammer),
                    nail: self.set(nail),
                    face: self.res.id(NameKind::Geom, face),
                    mocap,
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
            } => Compiled::Keypad {
                buttons: self.keypad_buttons(buttons),
                fingers: self.set(fingers),
                password: password.clone(),
                state: Keypad::default(),
            },
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
                base: self.res.id(NameKind::Body, base),
                posts: self.sites(posts),
                disks: self.hanoi_disks(disks),
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
            _ => unreachable!("node() sends only scene mechanics here"),
        })
    }

    /// The mocap id of the nail's body (which must be a mocap body; 0 when the body is
    /// missing, which the resolver reports).
    fn nail_mocap(&mut self, nail_body: &str) -> Result<usize, SimError> {
        let body = self.res.id(NameKind::Body, nail_body);
        let mocap = self.model.body_mocapid().get(body).copied().unwrap_or(-1);
        if body != usize::MAX && mocap < 0 {
            return Err(SimError::NotMocap(nail_body.to_string()));
        }
        Ok(mocap.max(0) as usize)
    }

    /// The keypad's buttons as (geom id, digit), sorted.
    fn keypad_buttons(&mut self, buttons: &[KeypadButton]) -> Vec<(usize, u8)> {
        let mut b: Vec<(usize, u8)> = buttons
            .iter()
            .map(|b| (self.res.id(NameKind::Geom, &b.geom), b.digit))
            .collect();
        // New presses are handled in ascending geom id order.
        b.sort();
        b
    }

    /// The Hanoi disks' free joints as (qpos address, dof address).
    fn hanoi_disks(&mut self, disks: &[HanoiDisk]) -> Vec<(usize, usize)> {
        disks
            .iter()
            .map(|d| {
                let j = self.res.id(NameKind::Joint, &d.joint);
                let q = self.model.jnt_qposadr().get(j).map_or(0, |a| *a as usize);
                let v = self.model.jnt_dofadr().get(j).map_or(0, |a| *a as usize);
                (q, v)
            })
            .collect()
    }
}

pub(super) fn output_names(c: &Compiled) -> &'static [&'static str] {
    match c {
        Compiled::Held { .. } | Compiled::Counter { .. } => &["count"],
        Compiled::Seq { .. } => &["index", "wrong"],
        Compiled::Nail { .. } => &["depth"],
        Compiled::Keypad { .. } => &["failed", "index"],
        Compiled::Hanoi { .. } => &["illegal", "on_goal"],
        Compiled::Grasp { .. } => &["fingers"],
        _ => &[],
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
