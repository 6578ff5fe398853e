//! Render checks: every frame of a replay is watched as it is rendered (a frame of nearly
//! one colour, a camera's video repeating itself while the robot moves, NaN or infinity
//! in a depth frame), and the replay's stored arrays at commit (NaN or infinity); what
//! fails becomes the `flags` of its record. Per frame: one comparison with and one copy
//! of the camera's previous frame, one pass (mostly cut short) for the colour share, one
//! pass over the depth; no allocation after the first frame. Outputs do not depend on it.

pub(crate) mod inject;

use dexjoco_core::{ArmSetup, ArrayLayout, Episode, FrameArray, TaskSpec};
use dexjoco_formats::raw::{RenderCheck, RenderFlag};

/// Share of a frame's pixels that, within [`BLANK_TOLERANCE`] of one colour, make the
/// frame blank.
pub const BLANK_SHARE: f64 = 0.99;

/// Levels (of 255, per channel) a pixel may differ from a blank frame's colour.
pub const BLANK_TOLERANCE: u8 = 2;

/// Frames in a row, each byte-identical to the one before, that make a frozen video
/// (when the robot moved meanwhile).
pub const FROZEN_MIN_FRAMES: usize = 10;

/// How far a TCP must move (m) over a run of repeated frames to make it a frozen video.
pub const FROZEN_TCP_M: f64 = 0.03;

/// How far a hand joint must turn (rad) over a run of repeated frames to make it a
/// frozen video.
pub const FROZEN_HAND_RAD: f64 = 0.3;

/// The checks of one replay: fed its frames camera by camera as they are rendered, then
/// its stored arrays at commit.
pub(crate) struct ReplayChecks {
    cameras: Vec<CameraChecks>,
    flags: Vec<RenderFlag>,
}

/// What is watched of one camera.
struct CameraChecks {
    name: String,
    width: usize,
    /// The last frame's pixels (empty before the first, and after a blank one).
    previous: Vec<u8>,
    /// The open run of blank frames.
    blank: Option<BlankRun>,
    /// The first frame of the open run of frames repeating their previous one.
    repeat_from: Option<usize>,
    /// Runs of repeated frames long enough to be a frozen video, if the robot moved.
    repeats: Vec<(usize, usize)>,
    /// The open run of depth frames holding non-finite values.
    depth: Option<NonFiniteRun>,
    /// The longest run of repeated frames, long or not (logged, to judge the threshold).
    longest: Option<(usize, usize)>,
    /// Frames seen.
    frames: usize,
}

/// Consecutive blank frames of one colour.
struct BlankRun {
    first: usize,
    last: usize,
    colour: [u8; 3],
    /// The smallest share of pixels of that colour over the run.
    share: f64,
}

/// Consecutive frames (or rows) holding NaN or infinity.
struct NonFiniteRun {
    first: usize,
    last: usize,
    nan: bool,
    inf: bool,
    /// Columns (or pixels) holding them, sorted, the first few.
    at: Vec<usize>,
    /// Whether more positions held them than `at` names.
    more: bool,
    /// How many values in all.
    count: usize,
}

/// Columns or pixels a non-finite flag names before "and N more".
const NAMED_POSITIONS: usize = 4;

impl ReplayChecks {
    /// Checks for a replay with these cameras (in render order), `width` pixels wide.
    pub(crate) fn new(cameras: &[String], width: u32) -> Self {
        Self {
            cameras: cameras
                .iter()
                .map(|name| CameraChecks {
                    name: name.clone(),
                    width: width as usize,
                    previous: Vec::new(),
                    blank: None,
                    repeat_from: None,
                    repeats: Vec::new(),
                    depth: None,
                    longest: None,
                    frames: 0,
                })
                .collect(),
            flags: Vec::new(),
        }
    }

    /// Watches frame `k` of camera `camera` (its RGB8 pixels and depth, if any).
    pub(crate) fn frame(&mut self, camera: usize, k: usize, rgb: &[u8], depth: Option<&[f32]>) {
        let c = &mut self.cameras[camera];
        c.frames = k + 1;
        let blank = blank_colour(rgb);
        c.watch_blank(k, blank, &mut self.flags);
        if blank.is_some() {
            // A blank frame is flagged as such, not as a repeat.
            c.close_repeat(k);
            c.previous.clear();
        } else if !c.previous.is_empty() && c.previous == rgb {
            c.repeat_from.get_or_insert(k);
        } else {
            c.close_repeat(k);
            c.previous.clear();
            c.previous.extend_from_slice(rgb);
        }
        if let Some(depth) = depth
            && let Some(run) = watch_non_finite(depth, k, &mut c.depth)
        {
            self.flags.push(c.depth_flag(&run));
        }
    }

    /// The flags of the replay, sorted: its frames' (watched so far) and those of its
    /// stored arrays (`ep`, whose `state` says how far the robot moved).
    pub(crate) fn finish(mut self, ep: &Episode, spec: &TaskSpec) -> Vec<RenderFlag> {
        let state = ep.array(Episode::STATE);
        for c in &mut self.cameras {
            let end = c.frames;
            c.watch_blank(end, None, &mut self.flags);
            c.close_repeat(end);
            if let Some(run) = c.depth.take() {
                self.flags.push(c.depth_flag(&run));
            }
            if let (Some((from, to)), Some(s)) = (c.longest, state) {
                let (tcp, hand) = robot_motion(s, spec.setup, from - 1, to);
                tracing::debug!(
                    camera = %c.name,
                    "render checks: longest run of repeated frames {from}-{to} ({} frames), \
                     TCP moved {tcp:.4} m, hand joints {hand:.3} rad",
                    to + 1 - from
                );
            }
            for &(from, to) in &c.repeats {
                if let Some(flag) =
                    state.and_then(|s| frozen_flag(&c.name, s, spec.setup, from, to))
                {
                    self.flags.push(flag);
                }
            }
        }
        for (name, a) in &ep.arrays {
            let layout = match name.as_str() {
                Episode::STATE => Some(spec.state_layout()),
                Episode::ACTION => Some(spec.setup.action_layout()),
                Episode::ACTION_ROTVEC => Some(spec.setup.action_rotvec_layout()),
                _ => None,
            };
            array_non_finite(name, a, layout.as_ref(), &mut self.flags);
        }
        self.flags.sort_by(|a, b| {
            (a.check, &a.camera, &a.array, a.first_frame).cmp(&(
                b.check,
                &b.camera,
                &b.array,
                b.first_frame,
            ))
        });
        self.flags
    }
}

impl CameraChecks {
    /// Extends, starts or closes the run of blank frames with frame `k` (`None`: not blank).
    fn watch_blank(
        &mut self,
        k: usize,
        blank: Option<([u8; 3], f64)>,
        flags: &mut Vec<RenderFlag>,
    ) {
        let same =
            |run: &BlankRun, colour: [u8; 3]| near(&run.colour, &colour) && run.last + 1 == k;
        match (self.blank.as_mut(), blank) {
            (Some(run), Some((colour, share))) if same(run, colour) => {
                run.last = k;
                run.share = run.share.min(share);
                return;
            }
            _ => {}
        }
        if let Some(run) = self.blank.take() {
            flags.push(blank_flag(&self.name, &run));
        }
        self.blank = blank.map(|(colour, share)| BlankRun {
            first: k,
            last: k,
            colour,
            share,
        });
    }

    /// The flag of a run of depth frames holding NaN or infinity (`<camera>_depth`).
    fn depth_flag(&self, run: &NonFiniteRun) -> RenderFlag {
        let w = self.width.max(1);
        non_finite_flag(run, format!("{}_depth", self.name), |i| {
            format!("pixel ({}, {})", i % w, i / w)
        })
    }

    /// Ends the open run of repeated frames before frame `k`, keeping it when long enough.
    fn close_repeat(&mut self, k: usize) {
        let Some(from) = self.repeat_from.take() else {
            return;
        };
        if self.longest.is_none_or(|(a, b)| b - a < k - 1 - from) {
            self.longest = Some((from, k - 1));
        }
        if k - from >= FROZEN_MIN_FRAMES {
            self.repeats.push((from, k - 1));
        }
    }
}

/// Whether two colours are within [`BLANK_TOLERANCE`] of each other on every channel.
fn near(a: &[u8], b: &[u8; 3]) -> bool {
    a.iter()
        .zip(b)
        .all(|(x, y)| x.abs_diff(*y) <= BLANK_TOLERANCE)
}

/// The colour at least [`BLANK_SHARE`] of the pixels are near, with their share, if the
/// frame is blank. The colour tried is the one of 16 spread pixels that most of the others
/// are near; the pass over the pixels stops as soon as too many are not.
pub(crate) fn blank_colour(rgb: &[u8]) -> Option<([u8; 3], f64)> {
    const SAMPLES: usize = 16;
    let n = rgb.len() / 3;
    if n == 0 {
        return None;
    }
    let may_differ = n - (n as f64 * BLANK_SHARE).ceil() as usize;
    let px = |i: usize| [rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]];
    let samples: [[u8; 3]; SAMPLES] = std::array::from_fn(|s| px((2 * s + 1) * n / (2 * SAMPLES)));
    let agreeing = |a: &[u8; 3]| samples.iter().filter(|b| near(*b, a)).count();
    let mut colour = samples[0];
    for s in &samples[1..] {
        if agreeing(s) > agreeing(&colour) {
            colour = *s;
        }
    }
    // Every pixel once, in interleaved passes over the whole frame (every `STRIDE`th
    // pixel from 0, then from 1...), so that a frame that is not blank shows it early
    // even when its first rows are all of one colour.
    const STRIDE: usize = 61;
    let lo = colour.map(|c| c.saturating_sub(BLANK_TOLERANCE));
    let hi = colour.map(|c| c.saturating_add(BLANK_TOLERANCE));
    let span = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    let mut differ = 0;
    for start in 0..STRIDE.min(n) {
        for px in rgb[3 * start..].chunks_exact(3).step_by(STRIDE) {
            let off = px[0].wrapping_sub(lo[0]) > span[0]
                || px[1].wrapping_sub(lo[1]) > span[1]
                || px[2].wrapping_sub(lo[2]) > span[2];
            if off {
                differ += 1;
                if differ > may_differ {
                    return None;
                }
            }
        }
    }
    Some((colour, (n - differ) as f64 / n as f64))
}

/// The flag of a run of blank frames.
fn blank_flag(camera: &str, run: &BlankRun) -> RenderFlag {
    let [r, g, b] = run.colour;
    let share = if run.share >= 1.0 {
        "every pixel".to_owned()
    } else {
        format!("{:.1} % of the pixels", 100.0 * run.share)
    };
    RenderFlag {
        check: RenderCheck::BlankFrame,
        camera: Some(camera.to_owned()),
        array: None,
        first_frame: run.first,
        last_frame: run.last,
        detail: format!("{share} within {BLANK_TOLERANCE} levels of ({r}, {g}, {b})"),
    }
}

/// How far the robot moved over frames `from..=to` of `state`: the largest displacement
/// of a TCP from its place at `from` (m), and the largest turn of a hand joint (rad).
pub(crate) fn robot_motion(
    state: &FrameArray,
    setup: ArmSetup,
    from: usize,
    to: usize,
) -> (f64, f64) {
    let layout = setup.proprio_layout();
    let mut tcp: f64 = 0.0;
    let mut hand: f64 = 0.0;
    if state.width() < layout.width() || to >= state.len() {
        return (0.0, 0.0);
    }
    let start = state.row(from);
    for k in from + 1..=to {
        let row = state.row(k);
        for f in &layout.fields {
            let cols = f.start..f.start + f.len;
            if f.name.ends_with(".tcp_pos") {
                let d2: f64 = cols.map(|i| (row[i] - start[i]).powi(2)).sum();
                tcp = tcp.max(d2.sqrt());
            } else if f.name.ends_with(".hand_qpos") {
                for i in cols {
                    hand = hand.max((row[i] - start[i]).abs());
                }
            }
        }
    }
    (tcp, hand)
}

/// The flag of frames `from..=to` of `camera` repeating frame `from - 1`, when the robot
/// moved meanwhile.
fn frozen_flag(
    camera: &str,
    state: &FrameArray,
    setup: ArmSetup,
    from: usize,
    to: usize,
) -> Option<RenderFlag> {
    let (tcp, hand) = robot_motion(state, setup, from - 1, to);
    (tcp > FROZEN_TCP_M || hand > FROZEN_HAND_RAD).then(|| RenderFlag {
        check: RenderCheck::FrozenVideo,
        camera: Some(camera.to_owned()),
        array: None,
        first_frame: from,
        last_frame: to,
        detail: format!(
            "{} frames repeat frame {} byte for byte while the TCP moved up to {tcp:.3} m \
             and the hand joints up to {hand:.2} rad",
            to + 1 - from,
            from - 1
        ),
    })
}

/// Watches frame (or row) `k`'s `values` for NaN and infinity: extends the `open` run
/// with them, or starts one; returns the run this frame ended, if any.
fn watch_non_finite<T: Copy + Into<f64>>(
    values: &[T],
    k: usize,
    open: &mut Option<NonFiniteRun>,
) -> Option<NonFiniteRun> {
    if values.iter().all(|v| (*v).into().is_finite()) {
        return open.take();
    }
    let ended = open.take_if(|r| r.last + 1 != k);
    let run = open.get_or_insert(NonFiniteRun {
        first: k,
        last: k,
        nan: false,
        inf: false,
        at: Vec::new(),
        more: false,
        count: 0,
    });
    run.last = k;
    for (i, v) in values.iter().enumerate() {
        let v: f64 = (*v).into();
        if v.is_finite() {
            continue;
        }
        run.nan |= v.is_nan();
        run.inf |= v.is_infinite();
        run.count += 1;
        match run.at.binary_search(&i) {
            Ok(_) => {}
            Err(_) if run.at.len() >= NAMED_POSITIONS => run.more = true,
            Err(p) => run.at.insert(p, i),
        }
    }
    ended
}

/// The flag of a run of non-finite values in `array`, its positions named by `position`.
fn non_finite_flag(
    run: &NonFiniteRun,
    array: String,
    position: impl Fn(usize) -> String,
) -> RenderFlag {
    let what = match (run.nan, run.inf) {
        (true, true) => "NaN and infinity",
        (true, false) => "NaN",
        _ => "infinity",
    };
    let at: Vec<String> = run.at.iter().map(|&i| position(i)).collect();
    RenderFlag {
        check: RenderCheck::NonFinite,
        camera: None,
        array: Some(array),
        first_frame: run.first,
        last_frame: run.last,
        detail: format!(
            "{what} at {}{} ({} value{})",
            at.join(", "),
            if run.more { " and more" } else { "" },
            run.count,
            if run.count == 1 { "" } else { "s" }
        ),
    }
}

/// Flags the runs of rows of the stored array `name` that hold NaN or infinity, naming
/// the columns by `layout` where known.
fn array_non_finite(
    name: &str,
    a: &FrameArray,
    layout: Option<&ArrayLayout>,
    flags: &mut Vec<RenderFlag>,
) {
    if a.as_slice().iter().all(|v| v.is_finite()) {
        return;
    }
    let column = |i: usize| match layout {
        Some(l) if i < l.width() => format!("column {i} ({})", l.column_name(i)),
        _ => format!("column {i}"),
    };
    let mut open = None;
    for k in 0..a.len() {
        if let Some(run) = watch_non_finite(a.row(k), k, &mut open) {
            flags.push(non_finite_flag(&run, name.to_owned(), column));
        }
    }
    if let Some(run) = open {
        flags.push(non_finite_flag(&run, name.to_owned(), column));
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;

    const W: usize = 32;

    /// A frame of one colour.
    fn flat(c: [u8; 3]) -> Vec<u8> {
        c.repeat(W * W)
    }

    /// A frame like a render: a gradient, `shift` moving it.
    fn picture(shift: usize) -> Vec<u8> {
        (0..W * W)
            .flat_map(|i| {
                let (x, y) = (i % W, i / W);
                [(x * 7 + shift) as u8, (y * 5) as u8, ((x + y) * 3) as u8]
            })
            .collect()
    }

    fn spec() -> &'static TaskSpec {
        TaskSpec::builtin("click_mouse").expect("built in")
    }

    /// An episode of `n` frames of click_mouse whose TCP moves `step` m a frame.
    fn episode(n: usize, step: f64) -> Episode {
        let s = spec();
        let mut state = FrameArray::zeros(n, s.state_layout().width());
        for k in 0..n {
            state.row_mut(k)[0] = k as f64 * step;
        }
        let mut arrays = BTreeMap::new();
        arrays.insert(Episode::STATE.to_owned(), state);
        arrays.insert(
            Episode::ACTION.to_owned(),
            FrameArray::zeros(n, s.setup.action_dim()),
        );
        Episode {
            id: "ep".into(),
            task: s.id.clone(),
            prompt: String::new(),
            fps: 30.0,
            arrays,
            cameras: Vec::new(),
        }
    }

    fn checks() -> ReplayChecks {
        ReplayChecks::new(&["cam".to_owned()], W as u32)
    }

    #[test]
    fn a_frame_of_one_colour_with_a_few_stray_pixels_is_blank_and_a_picture_is_not() {
        let mut f = flat([0, 0, 0]);
        // 8 stray pixels (0.8 %), some on the sampled ones, and noise within the tolerance.
        for i in [0, 32, 96, 500, 512, 700, 1000, 1023] {
            f[3 * i..3 * i + 3].copy_from_slice(&[255, 255, 255]);
        }
        f[3 * 300] = 2;
        let (colour, share) = blank_colour(&f).expect("blank");
        assert_eq!(colour, [0, 0, 0]);
        assert!((share - 1016.0 / 1024.0).abs() < 1e-12, "{share}");
        assert_eq!(blank_colour(&flat([40, 90, 200])).unwrap().1, 1.0);
        // 12 stray pixels (1.2 %) are too many; a picture is far from blank.
        for i in 1..=4 {
            f[3 * (200 + i)..3 * (200 + i) + 3].copy_from_slice(&[9, 9, 9]);
        }
        assert_eq!(blank_colour(&f), None);
        assert_eq!(blank_colour(&picture(0)), None);
    }

    #[test]
    fn consecutive_blank_frames_merge_into_one_flag() {
        let mut c = checks();
        for k in 0..12 {
            let f = if (3..=7).contains(&k) {
                flat([0, 0, 0])
            } else {
                picture(k)
            };
            c.frame(0, k, &f, None);
        }
        let flags = c.finish(&episode(12, 0.01), spec());
        assert_eq!(flags.len(), 1, "{flags:?}");
        let f = &flags[0];
        assert_eq!(f.check, RenderCheck::BlankFrame);
        assert_eq!(f.camera.as_deref(), Some("cam"));
        assert_eq!((f.first_frame, f.last_frame), (3, 7));
        assert_eq!(f.detail, "every pixel within 2 levels of (0, 0, 0)");
    }

    /// Flags of 30 frames of which 5..=20 repeat frame 4, the TCP moving `step` a frame.
    fn repeated_frames(step: f64) -> Vec<RenderFlag> {
        let mut c = checks();
        for k in 0..30 {
            let shift = if (5..=20).contains(&k) { 4 } else { k };
            c.frame(0, k, &picture(shift), None);
        }
        c.finish(&episode(30, step), spec())
    }

    #[test]
    fn a_video_repeating_itself_is_frozen_only_while_the_robot_moves() {
        // 16 frames x 5 mm: the TCP moved 8 cm.
        let flags = repeated_frames(0.005);
        assert_eq!(flags.len(), 1, "{flags:?}");
        let f = &flags[0];
        assert_eq!(f.check, RenderCheck::FrozenVideo);
        assert_eq!((f.first_frame, f.last_frame), (5, 20));
        assert!(f.detail.contains("repeat frame 4"), "{}", f.detail);
        assert!(f.detail.contains("0.080 m"), "{}", f.detail);
        // At rest (or moving less than the threshold), a still video is right.
        assert!(repeated_frames(0.0).is_empty());
        assert!(repeated_frames(0.001).is_empty());
        // Fewer repeats than the threshold are not flagged however far the robot moves.
        let mut c = checks();
        for k in 0..30 {
            let shift = if (5..5 + FROZEN_MIN_FRAMES - 1).contains(&k) {
                4
            } else {
                k
            };
            c.frame(0, k, &picture(shift), None);
        }
        assert!(c.finish(&episode(30, 0.05), spec()).is_empty());
    }

    #[test]
    fn nan_and_infinity_are_flagged_with_array_frames_and_column() {
        let mut ep = episode(12, 0.0);
        let state = ep.arrays.get_mut(Episode::STATE).unwrap();
        state.row_mut(4)[1] = f64::NAN;
        state.row_mut(5)[1] = f64::NAN;
        state.row_mut(5)[9] = f64::NEG_INFINITY;
        state.row_mut(9)[1] = f64::NAN;
        ep.arrays.get_mut(Episode::ACTION).unwrap().row_mut(11)[0] = f64::INFINITY;
        let mut c = checks();
        for k in 0..12 {
            let mut depth = vec![1.0f32; W * W];
            if k == 2 {
                depth[W + 3] = f32::NAN;
            }
            c.frame(0, k, &picture(k), Some(&depth));
        }
        let flags = c.finish(&ep, spec());
        let got: Vec<(&str, usize, usize, &str)> = flags
            .iter()
            .map(|f| {
                assert_eq!(f.check, RenderCheck::NonFinite);
                let a = f.array.as_deref().unwrap();
                (a, f.first_frame, f.last_frame, f.detail.as_str())
            })
            .collect();
        assert_eq!(
            got,
            [
                (
                    "action",
                    11,
                    11,
                    "infinity at column 0 (arm.pos[0]) (1 value)"
                ),
                ("cam_depth", 2, 2, "NaN at pixel (3, 1) (1 value)"),
                (
                    "state",
                    4,
                    5,
                    "NaN and infinity at column 1 (arm.tcp_pos[1]), column 9 (arm.hand_qpos[2]) (3 values)"
                ),
                ("state", 9, 9, "NaN at column 1 (arm.tcp_pos[1]) (1 value)"),
            ]
        );
    }
}
