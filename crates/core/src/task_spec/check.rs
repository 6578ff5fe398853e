//! Checks of a [`TaskSpec`] beyond its types: references between nodes, the evaluation
//! order (no cycles), widths and ranges; and the scene names a spec refers to.

use std::collections::BTreeSet;

use super::*;

impl TaskSpec {
    /// The node names in an order where every node comes after its inputs: scene
    /// mechanics first, then depth-first by name.
    pub fn evaluation_order(&self) -> Result<Vec<String>, TaskSpecError> {
        let mut order = Vec::new();
        let mut done = BTreeSet::new();
        let mut visiting = BTreeSet::new();
        // Scene mechanics first: they may move objects (the nail) that other nodes read.
        let mechanics = self
            .nodes
            .iter()
            .filter(|(_, n)| n.kind() == ConstraintKind::Mechanic);
        let others = self
            .nodes
            .iter()
            .filter(|(_, n)| n.kind() != ConstraintKind::Mechanic);
        for (name, _) in mechanics.chain(others) {
            self.visit(name, &mut done, &mut visiting, &mut order)?;
        }
        Ok(order)
    }

    fn visit(
        &self,
        name: &str,
        done: &mut BTreeSet<String>,
        visiting: &mut BTreeSet<String>,
        order: &mut Vec<String>,
    ) -> Result<(), TaskSpecError> {
        if done.contains(name) {
            return Ok(());
        }
        if !visiting.insert(name.to_owned()) {
            return Err(self.invalid(&format!("nodes.{name}"), "depends on itself".into()));
        }
        let node = self
            .nodes
            .get(name)
            .ok_or_else(|| self.invalid(&format!("nodes.{name}"), "no such node".into()))?;
        for input in node.inputs() {
            let base = input.split('.').next().unwrap_or(input);
            self.visit(base, done, visiting, order)?;
        }
        visiting.remove(name);
        done.insert(name.to_owned());
        order.push(name.to_owned());
        Ok(())
    }

    /// An inconsistency at `field` (a key path such as `nodes.on_pad.radius`).
    pub(super) fn invalid(&self, field: &str, message: String) -> TaskSpecError {
        TaskSpecError::Invalid {
            file: String::new(),
            task: self.id.clone(),
            message: format!("field '{field}': {message}"),
        }
    }

    /// Checks what the types cannot: references between nodes resolve (and outputs
    /// exist), the graph has no cycle, the state width matches the layout, objects named
    /// by placements and derived poses exist, ranges and counts are sensible.
    pub fn validate(&self) -> Result<(), TaskSpecError> {
        // The id and the camera names become file and folder names.
        crate::safe_name("task id", &self.id).map_err(|e| self.invalid("id", e.to_string()))?;
        for (i, c) in self.cameras.iter().enumerate() {
            crate::safe_name("camera key", &c.key)
                .map_err(|e| self.invalid(&format!("cameras[{i}].key"), e.to_string()))?;
            crate::safe_name("camera name", &c.camera)
                .map_err(|e| self.invalid(&format!("cameras[{i}].camera"), e.to_string()))?;
        }
        self.validate_nodes()?;
        self.validate_state()?;
        self.validate_subtasks()?;
        if let Some(h) = &self.reset.hand_qpos
            && h.len() != crate::layout::HAND_DOF
        {
            return Err(self.invalid("reset.hand_qpos", format!("{} values, not 16", h.len())));
        }
        if self.step_cap == 0 {
            return Err(self.invalid("step_cap", "must not be 0".into()));
        }
        if self.cameras.is_empty() {
            return Err(self.invalid("cameras", "must not be empty".into()));
        }
        for (i, d) in self.dynamics.iter().enumerate() {
            let r = match d {
                DynamicsRandomization::MassScale { range, .. }
                | DynamicsRandomization::FrictionlossUniform { range, .. }
                | DynamicsRandomization::FrictionlossScale { range, .. }
                | DynamicsRandomization::StiffnessScale { range, .. } => range,
            };
            if r[0] > r[1] || r[0] < 0.0 {
                return Err(
                    self.invalid(&format!("dynamics[{i}].range"), format!("bad range {r:?}"))
                );
            }
        }
        Ok(())
    }

    /// The condition graph's checks: node names, references (and the outputs they
    /// name), each node's own fields, the success and failure nodes, no cycle.
    fn validate_nodes(&self) -> Result<(), TaskSpecError> {
        for (name, node) in &self.nodes {
            if name.contains('.') || name.is_empty() {
                return Err(self.invalid("nodes", format!("bad node name '{name}'")));
            }
            for input in node.inputs() {
                self.check_ref(&format!("nodes.{name}"), input)?;
            }
            if let Node::ValueThreshold { of, .. } = node
                && !of.contains('.')
            {
                return Err(self.invalid(
                    &format!("nodes.{name}.of"),
                    format!("value_threshold needs 'node.output', got '{of}'"),
                ));
            }
            self.validate_node(name, node)?;
        }
        self.check_ref("success", &self.success)?;
        if let Some(f) = &self.failure {
            self.check_ref("failure", f)?;
        }
        self.evaluation_order()?;
        Ok(())
    }

    /// A reference at `field` to a node (`on_pad`) or a node's output (`nail.depth`)
    /// resolves.
    fn check_ref(&self, field: &str, r: &str) -> Result<(), TaskSpecError> {
        let (base, out) = match r.split_once('.') {
            Some((b, o)) => (b, Some(o)),
            None => (r, None),
        };
        let node = self
            .nodes
            .get(base)
            .ok_or_else(|| self.invalid(field, format!("reference to unknown node '{base}'")))?;
        if let Some(o) = out
            && !node.outputs().contains(&o)
        {
            return Err(self.invalid(
                field,
                format!(
                    "node '{base}' has no output '{o}' (it has: {})",
                    node.outputs().join(", ")
                ),
            ));
        }
        Ok(())
    }

    /// The state's checks: the width matches the layout, object names are unique, and
    /// placements and derived poses name known objects.
    fn validate_state(&self) -> Result<(), TaskSpecError> {
        let width = self.state_layout().width();
        if width != self.state.width {
            return Err(self.invalid(
                "state.width",
                format!("{} does not match the layout ({width})", self.state.width),
            ));
        }
        let objects: BTreeSet<&str> = self.state.objects.iter().map(|o| o.name.as_str()).collect();
        if objects.len() != self.state.objects.len() {
            return Err(self.invalid("state.objects", "duplicate names".into()));
        }
        for (i, p) in self.placement.iter().enumerate() {
            if !objects.contains(p.object.as_str()) {
                return Err(self.invalid(
                    &format!("placement[{i}].object"),
                    format!("unknown object '{}'", p.object),
                ));
            }
            if p.yaw_deg < 0.0 || p.axes[0] == p.axes[1] {
                return Err(self.invalid(
                    &format!("placement[{i}]"),
                    format!("bad placement of '{}'", p.object),
                ));
            }
        }
        for (i, d) in self.state.derived.iter().enumerate() {
            if let Some(f) = &d.from
                && !objects.contains(f.as_str())
            {
                return Err(self.invalid(
                    &format!("state.derived[{i}].from"),
                    format!("unknown object '{f}'"),
                ));
            }
        }
        Ok(())
    }

    fn validate_node(&self, name: &str, node: &Node) -> Result<(), TaskSpecError> {
        let bad = |what: &str| Err(self.invalid(&format!("nodes.{name}"), what.to_owned()));
        match node {
            Node::PointInCylinder { radius, along, .. }
                if *radius <= 0.0 || along[0] > along[1] =>
            {
                bad("radius must be > 0 and along ordered")
            }
            Node::PointInBox { min, max, .. } if (0..3).any(|i| min[i] > max[i]) => {
                bad("min must be <= max")
            }
            Node::PointInSiteBox { sites, .. } | Node::HeightAboveReset { sites, .. }
                if sites.is_empty() =>
            {
                bad("needs sites")
            }
            Node::AxisAlignment {
                target,
                max_angle_deg,
                ..
            } if target.iter().all(|v| *v == 0.0) || !(0.0..=180.0).contains(max_angle_deg) => {
                bad("target must be non-zero and the angle in [0, 180]")
            }
            Node::All { of } | Node::Any { of } if of.is_empty() => bad("needs inputs"),
            Node::Held { steps, .. } if *steps == 0 => bad("steps must be >= 1"),
            Node::Sequence { events } if events.is_empty() => bad("needs events"),
            Node::NailSinking {
                window,
                vz_divisor,
                min_vz,
                ..
            } if *window == 0 || *vz_divisor <= 0.0 || *min_vz >= 0.0 => {
                bad("window >= 1, vz_divisor > 0 and min_vz < 0")
            }
            Node::Keypad {
                buttons, password, ..
            } if password.is_empty()
                || password
                    .iter()
                    .any(|d| !buttons.iter().any(|b| b.digit == *d)) =>
            {
                bad("every password digit needs a button")
            }
            Node::HanoiTowers {
                posts,
                disks,
                goal_post,
                ..
            } if posts.is_empty() || disks.is_empty() || *goal_post >= posts.len() => {
                bad("needs posts, disks and a goal post among them")
            }
            Node::Grasp {
                min_fingers,
                opposed,
                ..
            } if !(1..=4 - u32::from(*opposed)).contains(min_fingers) => bad(
                "min_fingers must be 1 to 3 (opposed by the thumb or palm), 1 to 4 if not opposed",
            ),
            Node::Grasp { hand, .. }
                if (*hand == Hand::Single) != (self.setup == ArmSetup::SingleArm) =>
            {
                bad("hand must be `single` in a one-arm task, `left` or `right` in a two-arm one")
            }
            _ => Ok(()),
        }
    }

    /// Every scene name the spec refers to, by kind (`joint`, `body`, `site`, `geom`,
    /// `camera`, `sensor`), for checking against a scene.
    pub fn scene_names(&self) -> Vec<(NameKind, String)> {
        let mut out = Vec::new();
        let mut push = |k: NameKind, n: &str| out.push((k, n.to_owned()));
        for c in &self.cameras {
            push(NameKind::Camera, &c.camera);
        }
        push(NameKind::Body, &self.table.body);
        push(NameKind::Site, &self.table.top_site);
        for l in &self.table.legs {
            push(NameKind::Geom, l);
        }
        for j in self.reset.joint_qpos.keys() {
            push(NameKind::Joint, j);
        }
        let pose = |s: &PoseSource, push: &mut dyn FnMut(NameKind, &str)| match s {
            PoseSource::FreeJoint(n) => push(NameKind::Joint, n),
            PoseSource::Body(n) | PoseSource::Mocap(n) | PoseSource::BodyPosition(n) => {
                push(NameKind::Body, n)
            }
            PoseSource::GeomLocal(n) => push(NameKind::Geom, n),
        };
        for o in &self.state.objects {
            pose(&o.source, &mut push);
        }
        for d in &self.state.derived {
            pose(&d.target, &mut push);
        }
        for d in &self.dynamics {
            match d {
                DynamicsRandomization::MassScale { body, .. } => push(NameKind::Body, body),
                DynamicsRandomization::FrictionlossUniform { joint, .. }
                | DynamicsRandomization::FrictionlossScale { joint, .. }
                | DynamicsRandomization::StiffnessScale { joint, .. } => {
                    push(NameKind::Joint, joint)
                }
            }
        }
        for node in self.nodes.values() {
            node_scene_names(node, &mut push);
        }
        out.sort();
        out.dedup();
        out
    }
}

/// The scene names one condition node refers to, given to `push`.
fn node_scene_names(node: &Node, push: &mut dyn FnMut(NameKind, &str)) {
    let point = |p: &PointRef, push: &mut dyn FnMut(NameKind, &str)| match p {
        PointRef::Sensor(n) => push(NameKind::Sensor, n),
        PointRef::Site(n) => push(NameKind::Site, n),
        PointRef::Body(n) => push(NameKind::Body, n),
        PointRef::Geom(n) => push(NameKind::Geom, n),
    };
    let frame = |f: &FrameRef, push: &mut dyn FnMut(NameKind, &str)| match f {
        FrameRef::Site(n) => push(NameKind::Site, n),
        FrameRef::Body(n) => push(NameKind::Body, n),
        FrameRef::Geom(n) => push(NameKind::Geom, n),
    };
    let joint = |j: &JointRef, push: &mut dyn FnMut(NameKind, &str)| match j {
        JointRef::Sensor(n) => push(NameKind::Sensor, n),
        JointRef::Qpos(n) => push(NameKind::Joint, n),
    };
    let geoms = |g: &GeomSet, push: &mut dyn FnMut(NameKind, &str)| match g {
        GeomSet::Any => {}
        GeomSet::Geoms(v) => v.iter().for_each(|n| push(NameKind::Geom, n)),
        GeomSet::Subtree(b) | GeomSet::OutsideSubtree(b) => push(NameKind::Body, b),
    };
    match node {
        Node::PointInCylinder {
            point: p, center, ..
        } => {
            point(p, push);
            point(center, push);
        }
        Node::PointInBox {
            point: p, origin, ..
        } => {
            point(p, push);
            frame(origin, push);
        }
        Node::PointInSiteBox { point: p, sites } => {
            point(p, push);
            sites.iter().for_each(|s| push(NameKind::Site, s));
        }
        Node::HeightAboveReset { sites, .. } => sites.iter().for_each(|s| push(NameKind::Site, s)),
        Node::AboveReference {
            point: p,
            reference,
            ..
        } => {
            point(p, push);
            point(reference, push);
        }
        Node::AxisAlignment { frame: f, .. } => frame(f, push),
        Node::JointThreshold { joint: j, .. }
        | Node::JointAboveReset { joint: j, .. }
        | Node::JointHysteresis { joint: j, .. } => joint(j, push),
        Node::Contact { a, b, .. } => {
            geoms(a, push);
            geoms(b, push);
        }
        Node::Grasp { hand, object, .. } => {
            hand.fingers().iter().for_each(|b| push(NameKind::Body, b));
            push(NameKind::Body, &hand.palm());
            geoms(object, push);
        }
        Node::NailSinking {
            hammer,
            nail,
            face,
            nail_body,
            ..
        } => {
            hammer
                .iter()
                .chain(nail)
                .chain([face])
                .for_each(|g| push(NameKind::Geom, g));
            push(NameKind::Body, nail_body);
        }
        Node::Keypad {
            buttons, fingers, ..
        } => {
            buttons.iter().for_each(|b| push(NameKind::Geom, &b.geom));
            fingers.iter().for_each(|g| push(NameKind::Geom, g));
        }
        Node::HanoiTowers {
            base, posts, disks, ..
        } => {
            push(NameKind::Body, base);
            posts.iter().for_each(|s| push(NameKind::Site, s));
            disks.iter().for_each(|d| push(NameKind::Joint, &d.joint));
        }
        _ => {}
    }
}

/// Kinds of scene names a spec refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum NameKind {
    /// A joint.
    Joint,
    /// A body.
    Body,
    /// A site.
    Site,
    /// A geom.
    Geom,
    /// A camera.
    Camera,
    /// A sensor.
    Sensor,
    /// An actuator.
    Actuator,
}

impl NameKind {
    /// Lower-case name, e.g. `geom`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Joint => "joint",
            Self::Body => "body",
            Self::Site => "site",
            Self::Geom => "geom",
            Self::Camera => "camera",
            Self::Sensor => "sensor",
            Self::Actuator => "actuator",
        }
    }
}
