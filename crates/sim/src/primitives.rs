//! The building blocks of success conditions, free of MuJoCo so they can be tested on
//! constructed values: geometric tests (g_pose), stateful sequence logic (g_seq,
//! g_joint latches) and the scene mechanics (nail, keypad, Hanoi).
//!
//! [`crate::SuccessChecker`] reads the simulation and feeds these.

use std::collections::{BTreeSet, VecDeque};

use dexjoco_core::{Axis, Cmp, Threshold};

// ------------------------------------------------------------------ g_pose

/// `d = point - center` lies in a cylinder along a world axis: radial distance squared
/// <= radius^2 and the axial component in `along` (inclusive).
pub fn in_cylinder(
    point: [f64; 3],
    center: [f64; 3],
    axis: Axis,
    radius: f64,
    along: [f64; 2],
) -> bool {
    let d = sub(point, center);
    let a = axis.index();
    let radial2: f64 = (0..3).filter(|&i| i != a).map(|i| d[i] * d[i]).sum();
    radial2 <= radius * radius && d[a] >= along[0] && d[a] <= along[1]
}

/// `offset` (already in the box's axes) lies in [min, max], inclusive.
pub fn in_box(offset: [f64; 3], min: [f64; 3], max: [f64; 3]) -> bool {
    (0..3).all(|i| offset[i] >= min[i] && offset[i] <= max[i])
}

/// `R^T v` for a row-major 3x3 rotation matrix (world -> local).
pub fn to_local(xmat: &[f64; 9], v: [f64; 3]) -> [f64; 3] {
    [
        xmat[0] * v[0] + xmat[3] * v[1] + xmat[6] * v[2],
        xmat[1] * v[0] + xmat[4] * v[1] + xmat[7] * v[2],
        xmat[2] * v[0] + xmat[5] * v[1] + xmat[8] * v[2],
    ]
}

/// The point lies in the componentwise min/max box of `corners` (inclusive).
pub fn in_span(point: [f64; 3], corners: &[[f64; 3]]) -> bool {
    if corners.is_empty() {
        return false;
    }
    (0..3).all(|i| {
        let lo = corners.iter().map(|c| c[i]).fold(f64::INFINITY, f64::min);
        let hi = corners
            .iter()
            .map(|c| c[i])
            .fold(f64::NEG_INFINITY, f64::max);
        point[i] >= lo && point[i] <= hi
    })
}

/// Angle in degrees between column `axis` of a row-major rotation matrix and `target`.
pub fn axis_angle_deg(xmat: &[f64; 9], axis: Axis, target: [f64; 3]) -> f64 {
    let a = axis.index();
    let v = [xmat[a], xmat[3 + a], xmat[6 + a]];
    let dot: f64 = (0..3).map(|i| v[i] * target[i]).sum();
    let nv = norm(v);
    let nt = norm(target);
    (dot / (nv * nt)).clamp(-1.0, 1.0).acos().to_degrees()
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// `x op value` for a [`Threshold`].
pub fn holds(t: &Threshold, x: f64) -> bool {
    t.op.holds(x, t.value)
}

/// `x op value`.
pub fn compare(op: Cmp, x: f64, value: f64) -> bool {
    op.holds(x, value)
}

// ------------------------------------------------------------------ g_seq

/// Consecutive true steps, including the current one.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Hold {
    /// Steps in a row the input has been true.
    pub count: u32,
}

impl Hold {
    /// Feeds one step; true once the input has held `steps` steps in a row.
    pub fn update(&mut self, input: bool, steps: u32) -> bool {
        self.count = if input {
            self.count.saturating_add(1)
        } else {
            0
        };
        self.count >= steps
    }
}

/// Rising or falling edge detector (the previous value is false at reset).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Edge {
    prev: bool,
}

impl Edge {
    /// True when the input rose (false -> true) on this step.
    pub fn rising(&mut self, input: bool) -> bool {
        let r = input && !self.prev;
        self.prev = input;
        r
    }

    /// True when the input fell (true -> false) on this step.
    pub fn falling(&mut self, input: bool) -> bool {
        let f = !input && self.prev;
        self.prev = input;
        f
    }
}

/// Counts steps with a true input.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Count {
    /// Steps counted.
    pub count: u32,
}

impl Count {
    /// Feeds one step; true once the count reaches `at_least`.
    pub fn update(&mut self, input: bool, at_least: u32) -> bool {
        if input {
            self.count = self.count.saturating_add(1);
        }
        self.count >= at_least
    }
}

/// A set/clear latch: set wins over clear.
pub fn latch(state: &mut bool, set: bool, clear: bool) -> bool {
    if set {
        *state = true;
    } else if clear {
        *state = false;
    }
    *state
}

/// A latch with hysteresis on a value: cleared when `clear` holds (checked first), else
/// set when `set` holds, else unchanged.
pub fn hysteresis(state: &mut bool, x: f64, set: &Threshold, clear: &Threshold) -> bool {
    if holds(clear, x) {
        *state = false;
    } else if holds(set, x) {
        *state = true;
    }
    *state
}

/// Ordered events: the rising edges must come in order.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Sequence {
    /// Events matched so far.
    pub index: usize,
    /// An event came out of order (latched).
    pub wrong: bool,
    /// All events came in order (latched).
    pub done: bool,
    prev: Vec<bool>,
}

impl Sequence {
    /// Feeds the events' values this step; true once all came in order.
    pub fn update(&mut self, events: &[bool]) -> bool {
        self.prev.resize(events.len(), false);
        if !self.done {
            for (i, &e) in events.iter().enumerate() {
                if e && !self.prev[i] {
                    if i == self.index {
                        self.index += 1;
                        if self.index == events.len() {
                            self.done = true;
                            break;
                        }
                    } else {
                        self.wrong = true;
                        self.index = 0;
                    }
                }
            }
        }
        self.prev.copy_from_slice(events);
        self.done
    }
}

// ------------------------------------------------------------------ mechanics

/// The nail-sinking mechanic of hammer_nail.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Nail {
    /// Depth driven so far.
    pub depth: f64,
    /// The last face height sampled.
    pub prev_face_z: f64,
    /// The last `window` speeds.
    pub window: VecDeque<f64>,
}

/// Parameters of [`Nail`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NailParams {
    /// Samples kept.
    pub window: usize,
    /// Divisor of the per-substep height change.
    pub vz_divisor: f64,
    /// Speed threshold (negative).
    pub min_vz: f64,
    /// Depth per hit at unit scale.
    pub gain: f64,
    /// Largest scale.
    pub max_scale: f64,
    /// Largest depth.
    pub max_depth: f64,
}

impl Nail {
    /// Reset: depth 0, the face height as the previous sample, an empty window.
    pub fn reset(&mut self, face_z: f64) {
        self.depth = 0.0;
        self.prev_face_z = face_z;
        self.window.clear();
    }

    /// After one physics substep: sample the face speed.
    pub fn sample(&mut self, face_z: f64, p: &NailParams) {
        let vz = (face_z - self.prev_face_z) / p.vz_divisor;
        self.prev_face_z = face_z;
        self.window.push_back(vz);
        while self.window.len() > p.window {
            self.window.pop_front();
        }
    }

    /// After the step: with a hammer-nail contact and a fast downward sample in the
    /// window, the nail sinks. Returns true when the depth grew.
    pub fn strike(&mut self, touching: bool, p: &NailParams) -> bool {
        if !touching || self.window.is_empty() {
            return false;
        }
        let v = self.window.iter().copied().fold(f64::INFINITY, f64::min);
        if v >= p.min_vz {
            return false;
        }
        let scale = (v.abs() / p.min_vz.abs()).min(p.max_scale);
        let depth = (self.depth + p.gain * scale).min(p.max_depth);
        let grew = depth > self.depth;
        self.depth = depth;
        grew
    }
}

/// The keypad mechanic of unlock_ipad.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Keypad {
    /// Digits entered correctly so far.
    pub index: usize,
    /// A wrong digit was entered (latched until reset).
    pub failed: bool,
    /// The password was completed (latched; the buttons are hidden after it).
    pub unlocked: bool,
    /// The digits of the buttons newly pressed on the last update, in button order,
    /// right or wrong (the reference's `pressed_digits` of that step).
    pub last: Vec<u8>,
    pressed: BTreeSet<usize>,
}

impl Keypad {
    /// Feeds the buttons pressed this step (as indices into the keypad's buttons, in
    /// ascending geom id order) and their digits. Returns unlocked.
    pub fn update(
        &mut self,
        pressed: &BTreeSet<usize>,
        digit_of: impl Fn(usize) -> u8,
        password: &[u8],
    ) -> bool {
        self.last.clear();
        if self.unlocked {
            return true;
        }
        let new: Vec<usize> = pressed.difference(&self.pressed).copied().collect();
        self.pressed = pressed.clone();
        for b in new {
            if self.unlocked {
                // A second new press in the completing step: the reference raises here;
                // the buttons are gone, so it is ignored.
                break;
            }
            self.last.push(digit_of(b));
            if password.get(self.index) == Some(&digit_of(b)) {
                self.index += 1;
                if self.index == password.len() {
                    self.unlocked = true;
                }
            } else {
                self.failed = true;
                self.index = 0;
            }
        }
        self.unlocked
    }
}

/// One disk as the Hanoi mechanic sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiskState {
    /// Centre position.
    pub pos: [f64; 3],
    /// Norm of the 6-D free-joint velocity.
    pub speed: f64,
}

/// Parameters of [`Hanoi`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HanoiParams {
    /// Base top height above the base origin.
    pub top_offset: f64,
    /// Disk half-height.
    pub half_height: f64,
    /// Largest speed of a static disk.
    pub static_speed: f64,
    /// Largest xy distance to a post for a disk to be on it.
    pub post_radius: f64,
    /// A disk off the posts below top + this is on the table.
    pub table_margin: f64,
    /// Stack xy tolerance.
    pub xy_tol: f64,
    /// Stack z tolerance.
    pub z_tol: f64,
    /// Goal post index.
    pub goal_post: usize,
    /// Steps of one illegal reason that end the episode.
    pub illegal_steps: u32,
}

/// Why a Hanoi state is illegal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IllegalReason {
    /// A smaller disk under a larger one on this post, settled.
    Stack(usize),
    /// All disks settled, one of them on the table.
    DiskOnTable,
}

/// The Tower of Hanoi mechanic.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Hanoi {
    /// Steps the current illegal reason has lasted.
    pub illegal_count: u32,
    /// The reason of the last step.
    pub reason: Option<IllegalReason>,
    /// Illegal (latched: the episode ends).
    pub illegal: bool,
    /// Disks seated on the goal post in the goal order from the bottom (the largest
    /// first), its stack within tolerance: 2 once the medium disk is on the large one.
    pub on_goal: usize,
}

/// The per-post analysis of one Hanoi state.
#[derive(Debug, Clone, PartialEq)]
pub struct HanoiStacks {
    /// Disk indices per post, bottom first (index 0 = largest disk).
    pub posts: Vec<Vec<usize>>,
    /// Largest xy distance of a disk to its post, per post.
    pub xy_err: Vec<f64>,
    /// Largest z deviation from the expected slot, per post.
    pub z_err: Vec<f64>,
    /// Disks neither on a post nor in the air: on the table.
    pub on_table: Vec<usize>,
    /// Every disk is static.
    pub all_static: bool,
}

impl Hanoi {
    /// Assigns disks to posts (handled largest first; nearest post in xy, ties to the
    /// earlier post) and measures each stack.
    pub fn stacks(
        disks: &[DiskState],
        posts: &[[f64; 3]],
        base_z: f64,
        p: &HanoiParams,
    ) -> HanoiStacks {
        let top = base_z + p.top_offset;
        let mut on_post: Vec<Vec<usize>> = vec![Vec::new(); posts.len()];
        let mut on_table = Vec::new();
        for (i, d) in disks.iter().enumerate() {
            let mut best: Option<(usize, f64)> = None;
            for (k, post) in posts.iter().enumerate() {
                let dist = ((d.pos[0] - post[0]).powi(2) + (d.pos[1] - post[1]).powi(2)).sqrt();
                if best.is_none_or(|(_, b)| dist < b) {
                    best = Some((k, dist));
                }
            }
            match best {
                Some((k, dist)) if dist <= p.post_radius => on_post[k].push(i),
                _ if d.pos[2] <= top + p.table_margin => on_table.push(i),
                _ => {}
            }
        }
        let mut xy_err = vec![0.0; posts.len()];
        let mut z_err = vec![0.0; posts.len()];
        for (k, stack) in on_post.iter_mut().enumerate() {
            stack.sort_by(|a, b| disks[*a].pos[2].total_cmp(&disks[*b].pos[2]));
            for (level, &i) in stack.iter().enumerate() {
                let d = &disks[i];
                let xy =
                    ((d.pos[0] - posts[k][0]).powi(2) + (d.pos[1] - posts[k][1]).powi(2)).sqrt();
                let expected = top + (2 * level + 1) as f64 * p.half_height;
                xy_err[k] = f64::max(xy_err[k], xy);
                z_err[k] = f64::max(z_err[k], (d.pos[2] - expected).abs());
            }
        }
        HanoiStacks {
            posts: on_post,
            xy_err,
            z_err,
            on_table,
            all_static: disks.iter().all(|d| d.speed <= p.static_speed),
        }
    }

    /// Feeds one step; returns whether the goal holds (all disks on the goal post in
    /// order, within tolerance, static, and the state not illegal).
    pub fn update(
        &mut self,
        disks: &[DiskState],
        posts: &[[f64; 3]],
        base_z: f64,
        p: &HanoiParams,
    ) -> bool {
        let s = Self::stacks(disks, posts, base_z, p);
        let stack_ok = |k: usize| s.xy_err[k] <= p.xy_tol && s.z_err[k] <= p.z_tol;
        let mut reason = None;
        for (k, stack) in s.posts.iter().enumerate() {
            // A smaller disk (larger index) directly below a larger one.
            let inverted = stack.windows(2).any(|w| w[0] > w[1]);
            let settled = stack.iter().all(|&i| disks[i].speed <= p.static_speed);
            if inverted && settled && stack_ok(k) {
                reason = Some(IllegalReason::Stack(k));
                break;
            }
        }
        if reason.is_none() && s.all_static && !s.on_table.is_empty() {
            reason = Some(IllegalReason::DiskOnTable);
        }
        self.illegal_count = match reason {
            None => 0,
            Some(r) if Some(r) == self.reason => self.illegal_count + 1,
            Some(_) => 1,
        };
        self.reason = reason;
        if self.illegal_count >= p.illegal_steps {
            self.illegal = true;
        }
        let goal: Vec<usize> = (0..disks.len()).collect();
        self.on_goal = match s.posts.get(p.goal_post) {
            Some(st) if stack_ok(p.goal_post) => {
                st.iter().zip(&goal).take_while(|(a, b)| a == b).count()
            }
            _ => 0,
        };
        let others_empty = s
            .posts
            .iter()
            .enumerate()
            .all(|(k, st)| k == p.goal_post || st.is_empty());
        s.posts.get(p.goal_post) == Some(&goal)
            && others_empty
            && stack_ok(p.goal_post)
            && s.all_static
            && !self.illegal
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cylinder_box_span_and_axis() {
        // water_plant: r 0.2, dz in [-0.2, 0.2] around the plant.
        let c = [0.0, 0.0, 1.0];
        assert!(in_cylinder([0.1, 0.1, 1.1], c, Axis::Z, 0.2, [-0.2, 0.2]));
        assert!(!in_cylinder(
            [0.15, 0.15, 1.1],
            c,
            Axis::Z,
            0.2,
            [-0.2, 0.2]
        ));
        assert!(!in_cylinder([0.0, 0.0, 1.25], c, Axis::Z, 0.2, [-0.2, 0.2]));
        assert!(in_cylinder([0.0, 0.0, 0.8], c, Axis::Z, 0.2, [-0.2, 0.2]));
        // photograph: axis x, |dx| <= 0.10, radial <= 0.16.
        assert!(in_cylinder(
            [0.09, 0.1, 0.1],
            [0.0; 3],
            Axis::X,
            0.16,
            [-0.1, 0.1]
        ));
        assert!(!in_cylinder(
            [0.11, 0.0, 0.0],
            [0.0; 3],
            Axis::X,
            0.16,
            [-0.1, 0.1]
        ));
        assert!(!in_cylinder(
            [0.0, 0.12, 0.12],
            [0.0; 3],
            Axis::X,
            0.16,
            [-0.1, 0.1]
        ));

        assert!(in_box(
            [0.145, -0.145, 0.0275],
            [-0.145, -0.145, -0.045],
            [0.145, 0.145, 0.0275]
        ));
        assert!(!in_box(
            [0.0, 0.0, -0.046],
            [-0.145, -0.145, -0.045],
            [0.145, 0.145, 0.0275]
        ));
        // A body yawed 90 degrees: world +y is local -x... R = [[0,-1,0],[1,0,0],[0,0,1]].
        let r = [0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        assert_eq!(to_local(&r, [0.0, 1.0, 0.0]), [1.0, 0.0, 0.0]);

        let corners = [[0.0, 0.0, 0.0], [1.0, 2.0, 3.0], [0.5, -1.0, 1.0]];
        assert!(in_span([0.5, -0.5, 2.9], &corners));
        assert!(!in_span([0.5, 2.1, 1.0], &corners));
        assert!(!in_span([0.0; 3], &[]));

        let identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        assert!((axis_angle_deg(&identity, Axis::Z, [1.0, 0.0, 0.0]) - 90.0).abs() < 1e-12);
        // Rotation about y by 81 degrees: its z axis is 9 degrees from +x.
        let (s, c) = 81.0f64.to_radians().sin_cos();
        let tilted = [c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c];
        let a = axis_angle_deg(&tilted, Axis::Z, [1.0, 0.0, 0.0]);
        assert!((a - 9.0).abs() < 1e-9, "{a}");
    }

    #[test]
    fn hold_counts_n_minus_one_versus_n() {
        let mut h = Hold::default();
        for _ in 0..9 {
            assert!(!h.update(true, 10));
        }
        assert_eq!(h.count, 9);
        assert!(h.update(true, 10), "the 10th step in a row succeeds");
        assert!(!h.update(false, 10), "a false step resets");
        assert_eq!(h.count, 0);
        assert!(!h.update(true, 10));
    }

    #[test]
    fn edges_counters_and_latches() {
        let mut e = Edge::default();
        let seq = [false, true, true, false, true];
        let rises: Vec<bool> = seq.iter().map(|&x| e.rising(x)).collect();
        assert_eq!(rises, [false, true, false, false, true]);
        let mut e = Edge::default();
        let falls: Vec<bool> = seq.iter().map(|&x| e.falling(x)).collect();
        assert_eq!(falls, [false, false, false, true, false]);
        // Starting true counts as a rise (false at reset).
        assert!(Edge::default().rising(true));

        let mut c = Count::default();
        assert!(!c.update(true, 3));
        assert!(!c.update(false, 3));
        assert!(!c.update(true, 3));
        assert!(c.update(true, 3));
        assert!(c.update(false, 3), "a counter never goes down");

        let mut l = false;
        assert!(!latch(&mut l, false, false));
        assert!(latch(&mut l, true, false));
        assert!(latch(&mut l, false, false), "latched");
        assert!(latch(&mut l, true, true), "set wins");
        assert!(!latch(&mut l, false, true));
    }

    #[test]
    fn hysteresis_of_the_pinch_and_the_trigger() {
        // pinch_tongs: arm at >= 0.1, a pinch when closing to <= -0.07 while armed.
        let set = Threshold {
            op: Cmp::Ge,
            value: 0.1,
        };
        let clear = Threshold {
            op: Cmp::Le,
            value: -0.07,
        };
        let mut armed = false;
        let mut edge = Edge::default();
        let mut pinches = Count::default();
        let js = [
            0.227, 0.0, -0.07, -0.2, 0.05, 0.1, -0.069, -0.1, 0.2, -0.2, 0.2, -0.2,
        ];
        let mut done = false;
        for j in js {
            let a = hysteresis(&mut armed, j, &set, &clear);
            done = pinches.update(edge.falling(a), 3);
        }
        assert_eq!(pinches.count, 4);
        assert!(done);
        // water_plant: strict thresholds; 0.25 neither clears nor sets, 0.34 does not set.
        let set = Threshold {
            op: Cmp::Gt,
            value: 0.34,
        };
        let clear = Threshold {
            op: Cmp::Lt,
            value: 0.25,
        };
        let mut on = false;
        assert!(!hysteresis(&mut on, 0.34, &set, &clear));
        assert!(hysteresis(&mut on, 0.341, &set, &clear));
        assert!(hysteresis(&mut on, 0.25, &set, &clear), "holds in the band");
        assert!(!hysteresis(&mut on, 0.2499, &set, &clear));
    }

    #[test]
    fn sequence_in_order_and_out_of_order() {
        let mut s = Sequence::default();
        assert!(!s.update(&[true, false, false]));
        assert!(!s.update(&[true, false, false]), "a held event counts once");
        assert!(!s.update(&[false, true, false]));
        assert!(s.update(&[false, false, true]));
        assert!(!s.wrong);

        let mut s = Sequence::default();
        s.update(&[true, false, false]);
        s.update(&[false, false, true]);
        assert!(s.wrong && s.index == 0);
        assert!(
            !s.update(&[false, true, false]),
            "restarted: b first is wrong again"
        );
    }

    #[test]
    fn keypad_right_wrong_and_after_unlock() {
        let digits = [1u8, 2, 3, 4, 5, 6, 7, 8, 9, 0];
        let d = |i: usize| digits[i];
        let pw = [1, 2, 3];
        let set = |v: &[usize]| v.iter().copied().collect::<BTreeSet<usize>>();
        let mut k = Keypad::default();
        assert!(!k.update(&set(&[0]), d, &pw));
        assert!(
            !k.update(&set(&[0]), d, &pw),
            "holding the button is one press"
        );
        assert!(!k.update(&set(&[]), d, &pw));
        assert!(!k.update(&set(&[1]), d, &pw));
        assert_eq!(k.index, 2);
        assert!(k.update(&set(&[2]), d, &pw));
        assert!(k.unlocked && !k.failed);
        assert!(
            k.update(&set(&[5]), d, &pw),
            "after unlocking, presses are ignored"
        );

        let mut k = Keypad::default();
        k.update(&set(&[0]), d, &pw);
        k.update(&set(&[]), d, &pw);
        k.update(&set(&[0]), d, &pw); // "1" twice: wrong digit
        assert!(k.failed && k.index == 0 && !k.unlocked);
    }

    fn nail_params() -> NailParams {
        NailParams {
            window: 12,
            vz_divisor: 0.02,
            min_vz: -0.02,
            gain: 0.008,
            max_scale: 3.0,
            max_depth: 0.0726,
        }
    }

    #[test]
    fn nail_sinks_only_on_fast_touching_blows() {
        let p = nail_params();
        let mut n = Nail::default();
        n.reset(1.2);
        // Slow descent: 0.0003 m per substep = vz -0.015.
        let mut z = 1.2;
        for _ in 0..12 {
            z -= 0.0003;
            n.sample(z, &p);
        }
        assert!(!n.strike(true, &p));
        // Fast: 0.0008 m per substep = vz -0.04 = scale 2 -> +0.016.
        for _ in 0..3 {
            z -= 0.0008;
            n.sample(z, &p);
        }
        assert!(!n.strike(false, &p), "no contact, no depth");
        assert!(n.strike(true, &p));
        assert!((n.depth - 0.016).abs() < 1e-12, "{}", n.depth);
        // The same window scores again on the next step (no rising-edge test).
        assert!(n.strike(true, &p));
        // Very fast blows saturate at scale 3 and the depth caps at 0.0726.
        for _ in 0..12 {
            z -= 0.01;
            n.sample(z, &p);
        }
        for _ in 0..5 {
            n.strike(true, &p);
        }
        assert_eq!(n.depth, 0.0726);
        assert!(!n.strike(true, &p), "capped: no growth");
        assert_eq!(n.window.len(), 12);
    }

    fn hanoi_params() -> HanoiParams {
        HanoiParams {
            top_offset: 0.036,
            half_height: 0.02475,
            static_speed: 0.35,
            post_radius: 0.04,
            table_margin: 0.06,
            xy_tol: 0.04,
            z_tol: 0.012,
            goal_post: 2,
            illegal_steps: 10,
        }
    }

    fn posts() -> [[f64; 3]; 3] {
        [[0.0, 0.208, 1.0], [0.0, 0.0, 1.0], [0.0, -0.208, 1.0]]
    }

    fn disk(post: usize, level: usize) -> DiskState {
        let p = hanoi_params();
        let z = 0.92 + p.top_offset + (2 * level + 1) as f64 * p.half_height;
        DiskState {
            pos: [posts()[post][0], posts()[post][1], z],
            speed: 0.0,
        }
    }

    #[test]
    fn hanoi_goal_illegal_stack_and_table() {
        let p = hanoi_params();
        let mut h = Hanoi::default();
        // Reset preset: large on C, medium on B, small on A: legal, not the goal.
        let start = [disk(2, 0), disk(1, 0), disk(0, 0)];
        assert!(!h.update(&start, &posts(), 0.92, &p));
        assert!(!h.illegal && h.illegal_count == 0);
        // Goal: large, medium, small on C.
        let goal = [disk(2, 0), disk(2, 1), disk(2, 2)];
        assert!(h.update(&goal, &posts(), 0.92, &p));
        // Moving fast: not static, no success.
        let mut moving = goal;
        moving[2].speed = 0.5;
        assert!(!h.update(&moving, &posts(), 0.92, &p));
        // Small under medium on C: illegal after 10 steps of the same reason.
        let inverted = [disk(2, 0), disk(2, 2), disk(2, 1)];
        let s = Hanoi::stacks(&inverted, &posts(), 0.92, &p);
        assert_eq!(s.posts[2], vec![0, 2, 1]);
        let mut h = Hanoi::default();
        for i in 1..10 {
            h.update(&inverted, &posts(), 0.92, &p);
            assert_eq!(h.illegal_count, i);
            assert!(!h.illegal);
        }
        h.update(&inverted, &posts(), 0.92, &p);
        assert!(h.illegal, "the 10th step of one reason is illegal");
        assert!(!h.update(&goal, &posts(), 0.92, &p), "illegal is final");
        // A disk on the table; a change of reason restarts the count at 1.
        let mut on_table = start;
        on_table[2].pos = [0.3, 0.3, 0.92 + 0.036 + 0.02475];
        let mut h = Hanoi::default();
        h.update(&on_table, &posts(), 0.92, &p);
        assert_eq!(h.reason, Some(IllegalReason::DiskOnTable));
        h.update(&inverted, &posts(), 0.92, &p);
        assert_eq!(
            (h.reason, h.illegal_count),
            (Some(IllegalReason::Stack(2)), 1)
        );
        h.update(&start, &posts(), 0.92, &p);
        assert_eq!(h.illegal_count, 0);
    }
}
