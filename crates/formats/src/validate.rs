//! Validation of an episode against its task. Every check reports its first offending
//! frame and how many more there are, naming file, episode, field and frame.
//!
//! - [`integrity`]: what every command checks whichever door an episode comes in by
//!   (`ingest`, or `augment`, `convert` and `export` reading an MCAP log or a raw folder
//!   directly, through [`crate::Source::read_checked`]): array shapes against the task's
//!   layout, finite values, a finite positive frame rate, timestamps that increase at it;
//! - [`validate`]: `ingest`'s full check: the integrity checks, plus unit quaternions,
//!   hand target ranges, the step cap and the table offset.

use std::path::Path;

use crate::error::{Problem, ProblemCode};
use dexjoco_core::{
    ArmSetup, Episode, HAND_CTRL_RANGES, HAND_DOF, Location, POSE_DIM, PrivilegedKind,
    TABLE_OFFSET_RANGE, TaskSpec,
};

/// Tolerances of the checks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ValidationOptions {
    /// Allowed `abs(norm - 1)` of a quaternion.
    pub quat_norm_tolerance: f64,
    /// Allowed relative deviation of a timestamp step from `1 / fps`.
    pub timestep_tolerance: f64,
    /// Allowed excursion of a hand target beyond its control range (rad).
    pub hand_range_tolerance: f64,
    /// Allowed excursion of dh beyond [0, 0.05] (m).
    pub table_offset_tolerance: f64,
}

impl ValidationOptions {
    /// Default quaternion norm tolerance.
    pub const DEFAULT_QUAT_NORM_TOLERANCE: f64 = 1e-3;
    /// Default timestamp step tolerance (10 % of a frame).
    pub const DEFAULT_TIMESTEP_TOLERANCE: f64 = 0.1;
    /// Default hand range tolerance.
    pub const DEFAULT_HAND_RANGE_TOLERANCE: f64 = 1e-6;
    /// Default table offset tolerance.
    pub const DEFAULT_TABLE_OFFSET_TOLERANCE: f64 = 1e-9;
}

impl Default for ValidationOptions {
    fn default() -> Self {
        Self {
            quat_norm_tolerance: Self::DEFAULT_QUAT_NORM_TOLERANCE,
            timestep_tolerance: Self::DEFAULT_TIMESTEP_TOLERANCE,
            hand_range_tolerance: Self::DEFAULT_HAND_RANGE_TOLERANCE,
            table_offset_tolerance: Self::DEFAULT_TABLE_OFFSET_TOLERANCE,
        }
    }
}

/// Collects the first instance of each (code, field) and counts the rest.
struct Findings<'a> {
    base: Location,
    episode: &'a str,
    list: Vec<(Problem, usize)>,
}

impl<'a> Findings<'a> {
    fn new(ep: &'a Episode, source: &Path) -> Self {
        Self {
            base: Location::default().path(source),
            episode: &ep.id,
            list: Vec::new(),
        }
    }

    fn add(&mut self, code: ProblemCode, field: String, frame: Option<usize>, detail: String) {
        if let Some((_, more)) = self
            .list
            .iter_mut()
            .find(|(p, _)| p.code == code && p.field.as_deref() == Some(field.as_str()))
        {
            *more += 1;
            return;
        }
        let mut at = self.base.clone().field(field);
        at.episode = Some(self.episode.to_owned());
        at.frame = frame;
        self.list.push((Problem::new(code, &at, detail), 0));
    }

    fn finish(self) -> Vec<Problem> {
        self.list
            .into_iter()
            .map(|(mut p, more)| {
                if more > 0 {
                    p.message.push_str(&format!(" (and {more} more)"));
                }
                p
            })
            .collect()
    }
}

/// Checks an episode against its task; returns every problem found (empty = valid).
///
/// `source` names the file or folder the episode came from.
pub fn validate(
    ep: &Episode,
    task: &TaskSpec,
    source: &Path,
    opts: &ValidationOptions,
) -> Vec<Problem> {
    let mut f = Findings::new(ep, source);
    if integrity_checks(ep, task, opts, &mut f) {
        if ep.len() > task.step_cap {
            f.add(
                ProblemCode::TooLong,
                Episode::ACTION.into(),
                Some(task.step_cap),
                format!(
                    "{} frames exceed the step cap {} of {}",
                    ep.len(),
                    task.step_cap,
                    task.id
                ),
            );
        }
        check_action(ep, task.setup, opts, &mut f);
        check_state(ep, task, opts, &mut f);
    }
    f.finish()
}

/// The checks every reader applies to an episode whatever door it came in by: array
/// shapes and lengths against the task, finite values, the frame rate and the
/// timestamps (see the module documentation); returns every problem found.
pub fn integrity(
    ep: &Episode,
    task: &TaskSpec,
    source: &Path,
    opts: &ValidationOptions,
) -> Vec<Problem> {
    let mut f = Findings::new(ep, source);
    integrity_checks(ep, task, opts, &mut f);
    f.finish()
}

/// The integrity checks into `f`; true when the arrays are whole and finite (the
/// value checks can run).
fn integrity_checks(
    ep: &Episode,
    task: &TaskSpec,
    opts: &ValidationOptions,
    f: &mut Findings<'_>,
) -> bool {
    let setup = task.setup;
    let frames = ep.len();
    // Dimensions and lengths first: later checks index columns.
    let widths = [
        (Episode::ACTION, setup.action_dim()),
        (Episode::ACTION_ROTVEC, setup.action_rotvec_dim()),
        (Episode::STATE, task.state.width),
        (Episode::TIMESTAMP, 1),
    ];
    let mut shapes_ok = true;
    for (name, width) in widths {
        match ep.array(name) {
            None => {
                shapes_ok = false;
                f.add(
                    ProblemCode::MissingArray,
                    name.into(),
                    None,
                    "array is missing".into(),
                );
            }
            Some(a) if a.width() != width => {
                shapes_ok = false;
                f.add(
                    ProblemCode::WrongDimensions,
                    name.into(),
                    None,
                    format!(
                        "expected {width} values per frame for {} ({:?}), found {}",
                        task.id,
                        setup,
                        a.width()
                    ),
                );
            }
            Some(a) if a.len() != frames => {
                shapes_ok = false;
                f.add(
                    ProblemCode::WrongLength,
                    name.into(),
                    None,
                    format!("{} frames where the episode has {frames}", a.len()),
                );
            }
            Some(_) => {}
        }
    }
    if frames == 0 {
        f.add(
            ProblemCode::WrongLength,
            Episode::ACTION.into(),
            None,
            "the episode has no frames".into(),
        );
        shapes_ok = false;
    }
    if !shapes_ok {
        return false;
    }

    // Finite values everywhere.
    let mut any_nan = false;
    for (name, a) in &ep.arrays {
        for (i, row) in a.rows().enumerate() {
            for (c, v) in row.iter().enumerate() {
                if !v.is_finite() {
                    any_nan = true;
                    f.add(
                        ProblemCode::NotFinite,
                        column(name, a.width(), c),
                        Some(i),
                        format!("value {v} is not finite"),
                    );
                }
            }
        }
    }
    if any_nan {
        // Range checks on NaN data only repeat the finding.
        return false;
    }
    check_timestamps(ep, opts, f);
    true
}

fn column(name: &str, width: usize, c: usize) -> String {
    if width == 1 {
        name.to_owned()
    } else {
        format!("{name}[{c}]")
    }
}

fn check_timestamps(ep: &Episode, opts: &ValidationOptions, f: &mut Findings<'_>) {
    let ts = ep.array(Episode::TIMESTAMP).expect("checked").as_slice();
    let dt = 1.0 / ep.fps;
    if !(ep.fps.is_finite() && ep.fps > 0.0) {
        let why = if ep.fps.is_finite() {
            "is not positive"
        } else {
            "is not finite"
        };
        f.add(
            ProblemCode::Timestamps,
            "fps".into(),
            None,
            format!("frame rate {} {why}", ep.fps),
        );
        return;
    }
    for k in 1..ts.len() {
        let step = ts[k] - ts[k - 1];
        if step <= 0.0 {
            f.add(
                ProblemCode::Timestamps,
                Episode::TIMESTAMP.into(),
                Some(k),
                format!(
                    "timestamp {} does not increase (previous {})",
                    ts[k],
                    ts[k - 1]
                ),
            );
        } else if (step - dt).abs() > opts.timestep_tolerance * dt {
            f.add(
                ProblemCode::Timestamps,
                Episode::TIMESTAMP.into(),
                Some(k),
                format!(
                    "step {step:.6} s is not 1/{} s (within {} %)",
                    ep.fps,
                    opts.timestep_tolerance * 100.0
                ),
            );
        }
    }
}

fn check_quat(
    q: &[f64],
    field: String,
    frame: usize,
    opts: &ValidationOptions,
    f: &mut Findings<'_>,
) {
    let n = q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if (n - 1.0).abs() > opts.quat_norm_tolerance {
        f.add(
            ProblemCode::NotUnitQuaternion,
            field,
            Some(frame),
            format!(
                "quaternion {q:?} has norm {n:.6} (tolerance {})",
                opts.quat_norm_tolerance
            ),
        );
    }
}

fn check_action(ep: &Episode, setup: ArmSetup, opts: &ValidationOptions, f: &mut Findings<'_>) {
    let action = ep.array(Episode::ACTION).expect("checked");
    let per_arm = POSE_DIM + HAND_DOF;
    for (i, row) in action.rows().enumerate() {
        for arm in 0..setup.arms() {
            let a = &row[arm * per_arm..(arm + 1) * per_arm];
            let pose = &a[..POSE_DIM];
            // An all-zero pose means "hold the last target" and carries no quaternion.
            if !pose.iter().all(|v| v.abs() <= 1e-8) {
                check_quat(
                    &pose[3..7],
                    format!("action[{}..{}]", arm * per_arm + 3, arm * per_arm + 7),
                    i,
                    opts,
                    f,
                );
            }
            let hand = &a[POSE_DIM..];
            // All-zero hand targets are the recorder's "teleop not engaged" frames.
            if hand.iter().all(|v| *v == 0.0) {
                continue;
            }
            for (j, v) in hand.iter().enumerate() {
                let (lo, hi) = HAND_CTRL_RANGES[j];
                if *v < lo - opts.hand_range_tolerance || *v > hi + opts.hand_range_tolerance {
                    f.add(
                        ProblemCode::HandOutOfRange,
                        format!("action[{}]", arm * per_arm + POSE_DIM + j),
                        Some(i),
                        format!("hand target {v} outside the actuator range [{lo}, {hi}]"),
                    );
                }
            }
        }
    }
}

fn check_state(ep: &Episode, task: &TaskSpec, opts: &ValidationOptions, f: &mut Findings<'_>) {
    let state = ep.array(Episode::STATE).expect("checked");
    let privileged = task.privileged();
    for (i, row) in state.rows().enumerate() {
        for arm in 0..task.setup.arms() {
            let s = arm * POSE_DIM + 3;
            check_quat(&row[s..s + 4], format!("state[{s}..{}]", s + 4), i, opts, f);
        }
        for p in &privileged {
            match p.kind {
                PrivilegedKind::Pose => {
                    let s = p.start + 3;
                    check_quat(&row[s..s + 4], format!("state[{s}..{}]", s + 4), i, opts, f);
                }
                PrivilegedKind::Position => {}
                PrivilegedKind::TableOffset => {
                    let dh = row[p.start];
                    let (lo, hi) = TABLE_OFFSET_RANGE;
                    let tol = opts.table_offset_tolerance;
                    if dh < lo - tol || dh > hi + tol {
                        f.add(
                            ProblemCode::TableOffsetOutOfRange,
                            format!("state[{}]", p.start),
                            Some(i),
                            format!("table offset dh = {dh} outside [{lo}, {hi}] m"),
                        );
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dexjoco_core::synth;

    fn task_info(id: &str) -> Option<&'static TaskSpec> {
        TaskSpec::builtin(id)
    }

    fn codes(ep: &Episode, task: &TaskSpec) -> Vec<(ProblemCode, Option<String>, Option<usize>)> {
        validate(ep, task, Path::new("x"), &ValidationOptions::default())
            .into_iter()
            .map(|p| (p.code, p.field, p.frame))
            .collect()
    }

    #[test]
    fn synthetic_episodes_of_every_task_are_valid() {
        for task in dexjoco_core::TaskSet::builtin().iter() {
            let ep = synth::episode(task, 50, 7);
            assert_eq!(codes(&ep, task), vec![], "{}", task.id);
        }
    }

    #[test]
    fn each_check_names_field_and_frame() {
        let task = task_info("bimanual_assembly").unwrap();
        let base = synth::episode(task, 30, 1);

        let mut ep = base.clone();
        ep.arrays.get_mut("state").unwrap().row_mut(5)[60] = -0.01;
        ep.arrays.get_mut("state").unwrap().row_mut(6)[60] = -0.01;
        let c = codes(&ep, task);
        assert_eq!(
            c,
            vec![(
                ProblemCode::TableOffsetOutOfRange,
                Some("state[60]".into()),
                Some(5)
            )]
        );
        let msg = &validate(&ep, task, Path::new("x"), &ValidationOptions::default())[0].message;
        assert!(msg.contains("(and 1 more)"), "{msg}");

        // The left arm's quaternion (action[26..30]).
        let mut ep = base.clone();
        ep.arrays.get_mut("action").unwrap().row_mut(3)[26] = 2.0;
        assert_eq!(
            codes(&ep, task),
            vec![(
                ProblemCode::NotUnitQuaternion,
                Some("action[26..30]".into()),
                Some(3)
            )]
        );

        // An all-zero pose holds the target: no quaternion to check.
        let mut ep = base.clone();
        ep.arrays.get_mut("action").unwrap().row_mut(3)[..7].fill(0.0);
        assert_eq!(codes(&ep, task), vec![]);

        // All-zero hands (teleop not engaged) pass; a thumb base of 0 alone does not.
        let mut ep = base.clone();
        ep.arrays.get_mut("action").unwrap().row_mut(0)[7..23].fill(0.0);
        assert_eq!(codes(&ep, task), vec![]);
        ep.arrays.get_mut("action").unwrap().row_mut(1)[7 + 12] = 0.0;
        assert_eq!(
            codes(&ep, task),
            vec![(
                ProblemCode::HandOutOfRange,
                Some("action[19]".into()),
                Some(1)
            )]
        );

        // Timestamps at the wrong rate.
        let mut ep = base.clone();
        ep.arrays
            .insert("timestamp".into(), Episode::regular_timestamps(30, 15.0));
        assert_eq!(codes(&ep, task)[0].0, ProblemCode::Timestamps);

        // Object pose quaternion in the privileged state: the peg at [53:60].
        let mut ep = base.clone();
        ep.arrays.get_mut("state").unwrap().row_mut(2)[56] = 0.0;
        ep.arrays.get_mut("state").unwrap().row_mut(2)[57] = 0.0;
        let c = codes(&ep, task);
        assert_eq!(c[0].1.as_deref(), Some("state[56..60]"));

        // Wrong task width stops before value checks.
        let other = task_info("click_mouse").unwrap();
        let c = codes(&base, other);
        assert!(
            c.iter().all(|x| x.0 == ProblemCode::WrongDimensions),
            "{c:?}"
        );
        assert!(c.iter().any(|x| x.1.as_deref() == Some("action")));
    }
}
