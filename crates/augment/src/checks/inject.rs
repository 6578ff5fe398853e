//! A test hook: [`RENDER_DEFECT_ENV`] corrupts chosen frames of chosen replays after they
//! are rendered and before they are checked and written (and chosen values of a replay's
//! stored arrays before they are checked and written), so that tests can see each render
//! check catch its defect. Read by every unit, on threads and in worker processes (which
//! inherit the environment). Unset, it costs nothing.

use dexjoco_core::Episode;
use dexjoco_render::Frame;

use crate::error::AugmentError;

/// Environment variable of a test hook: comma-separated defects
/// `<replay>:<kind>:<target>:<frames>` injected after rendering, before the checks and
/// the writing. `<replay>` is a replay's folder name (`episode_000000__r01`) or its last
/// part (`r01`, every episode's replay 1), optionally after its task (`click_mouse/r01`). `<kind>` is `blank` (frames painted black),
/// `frozen` (frames replaced by the one before the range; the range starts at frame 1 or
/// later), `nan` or `inf` (a value set to NaN or +infinity). `<target>` is a camera
/// (`third_person`, ...) for `blank` and `frozen`; for `nan` and `inf` a stored array
/// (`state`, `action`, `action_rotvec`, `timestamp`) or a camera's depth
/// (`third_person_depth`), with an optional `[i]` (the column, or the depth frame's pixel
/// in row-major order; 0 if left out). `<frames>` is `k` or `a-b` (inclusive). Example:
/// `r00:blank:third_person:5-9,r01:frozen:third_person:3-20,r02:nan:state[4]:7`.
pub const RENDER_DEFECT_ENV: &str = "DEXJOCO_TEST_RENDER_DEFECT";

/// What a defect does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Blank,
    Frozen,
    Nan,
    Inf,
}

/// One injected defect.
#[derive(Debug, Clone, PartialEq, Eq)]
struct Defect {
    replay: String,
    kind: Kind,
    target: String,
    index: usize,
    first: usize,
    last: usize,
}

impl Defect {
    fn covers(&self, k: usize) -> bool {
        (self.first..=self.last).contains(&k)
    }

    fn value(&self) -> f64 {
        if self.kind == Kind::Nan {
            f64::NAN
        } else {
            f64::INFINITY
        }
    }
}

/// The defects of the hook, parsed.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(crate) struct Defects(Vec<Defect>);

impl Defects {
    /// The defects [`RENDER_DEFECT_ENV`] asks for (none when unset); an error naming the
    /// variable when it does not parse.
    pub(crate) fn from_env() -> Result<Self, AugmentError> {
        match std::env::var(RENDER_DEFECT_ENV) {
            Ok(s) => Self::parse(&s)
                .map_err(|e| AugmentError::Input(format!("{RENDER_DEFECT_ENV}='{s}': {e}"))),
            Err(_) => Ok(Self::default()),
        }
    }

    /// Parses `<replay>:<kind>:<target>:<frames>,...`.
    fn parse(s: &str) -> Result<Self, String> {
        let mut out = Vec::new();
        for entry in s.split(',').map(str::trim).filter(|e| !e.is_empty()) {
            let parts: Vec<&str> = entry.split(':').collect();
            let [replay, kind, target, frames] = parts[..] else {
                return Err(format!(
                    "'{entry}' is not <replay>:<kind>:<target>:<frames>"
                ));
            };
            let kind = match kind {
                "blank" => Kind::Blank,
                "frozen" => Kind::Frozen,
                "nan" => Kind::Nan,
                "inf" => Kind::Inf,
                _ => return Err(format!("'{kind}' is not blank, frozen, nan or inf")),
            };
            let number = |t: &str| {
                t.trim()
                    .parse::<usize>()
                    .map_err(|_| format!("'{t}' in '{entry}' is not a number"))
            };
            let (first, last) = match frames.split_once('-') {
                Some((a, b)) => (number(a)?, number(b)?),
                None => (number(frames)?, number(frames)?),
            };
            let (target, index) = match target.split_once('[') {
                Some((t, i)) => (t, number(i.trim_end_matches(']'))?),
                None => (target, 0),
            };
            if first > last || (kind == Kind::Frozen && first == 0) {
                return Err(format!(
                    "'{entry}': frames a-b need a <= b (a >= 1 for frozen)"
                ));
            }
            out.push(Defect {
                replay: replay.to_owned(),
                kind,
                target: target.to_owned(),
                index,
                first,
                last,
            });
        }
        Ok(Self(out))
    }

    /// The defects of the replay folder `name` (`<episode>__rNN`) of `task`, whose
    /// cameras are `cameras` in render order.
    pub(crate) fn for_replay(&self, task: &str, name: &str, cameras: &[String]) -> ReplayDefects {
        let chosen = |d: &&Defect| {
            let (t, r) = d.replay.split_once('/').unwrap_or((task, &d.replay));
            t == task && (r == name || name.ends_with(&format!("__{r}")))
        };
        let defects: Vec<Defect> = self.0.iter().filter(chosen).cloned().collect();
        ReplayDefects {
            held: vec![Vec::new(); if defects.is_empty() { 0 } else { cameras.len() }],
            cameras: cameras.to_vec(),
            defects,
        }
    }
}

/// The defects of one replay, and the last frame of each camera (to repeat it).
pub(crate) struct ReplayDefects {
    defects: Vec<Defect>,
    cameras: Vec<String>,
    held: Vec<Vec<u8>>,
}

impl ReplayDefects {
    /// Corrupts frame `k` of camera `camera` (index in render order) as asked.
    pub(crate) fn frame(&mut self, camera: usize, k: usize, frame: &mut Frame) {
        if self.defects.is_empty() {
            return;
        }
        let name = &self.cameras[camera];
        let depth_name = format!("{name}_depth");
        for d in self.defects.iter().filter(|d| d.covers(k)) {
            match d.kind {
                Kind::Blank if d.target == *name => frame.rgb.fill(0),
                Kind::Frozen if d.target == *name && !self.held[camera].is_empty() => {
                    frame.rgb.copy_from_slice(&self.held[camera]);
                }
                Kind::Nan | Kind::Inf if d.target == depth_name => {
                    if let Some(v) = frame.depth.as_mut().and_then(|p| p.get_mut(d.index)) {
                        *v = d.value() as f32;
                    }
                }
                _ => {}
            }
        }
        self.held[camera].clone_from(&frame.rgb);
    }

    /// Corrupts the replay's stored arrays as asked.
    pub(crate) fn episode(&self, ep: &mut Episode) {
        for d in &self.defects {
            if !matches!(d.kind, Kind::Nan | Kind::Inf) {
                continue;
            }
            let Some(a) = ep.arrays.get_mut(&d.target) else {
                continue;
            };
            let (w, n) = (a.width(), a.len());
            for k in (d.first..=d.last).filter(|&k| k < n && d.index < w) {
                a.row_mut(k)[d.index] = d.value();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_documented_syntax_and_refuses_the_rest() {
        let d = Defects::parse(
            "r00:blank:third_person:5-9, ep__r02:nan:state[4]:7,other/r03:inf:action:1",
        )
        .unwrap();
        assert_eq!(d.0.len(), 3);
        assert_eq!(d.0[0].kind, Kind::Blank);
        assert_eq!((d.0[0].first, d.0[0].last), (5, 9));
        assert_eq!((d.0[1].target.as_str(), d.0[1].index), ("state", 4));
        assert_eq!((d.0[1].first, d.0[1].last), (7, 7));
        let cams = vec!["third_person".to_owned()];
        let chosen = |task: &str, name: &str| d.for_replay(task, name, &cams).defects.len();
        assert_eq!(chosen("t", "ep__r00"), 1);
        assert_eq!(chosen("t", "ep__r02"), 1);
        assert_eq!(chosen("t", "other__r02"), 0);
        assert_eq!(chosen("t", "ep__r01"), 0);
        assert_eq!(chosen("t", "ep__r03"), 0);
        assert_eq!(chosen("other", "ep__r03"), 1);
        for bad in [
            "r00:blank:third_person",
            "r00:melt:third_person:1",
            "r00:frozen:third_person:0-3",
            "r00:nan:state:9-3",
            "r00:nan:state[x]:1",
        ] {
            assert!(Defects::parse(bad).is_err(), "{bad}");
        }
    }
}
