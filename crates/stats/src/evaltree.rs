//! Reading the folders the DexJoCo reference evaluator writes:
//! `<task>[_rand_full]_seed<s>/episode_XX_{success|failure}[_<digits>|_no_password_input]/`
//! plus an empty marker file `success_rate_<n>_<episodes>.txt` per run.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::StatsError;

/// The regime of a run folder without a `_rand_<x>` part: objects and table height
/// randomized only.
pub const DEFAULT_REGIME: &str = "rand_obj";

/// What an episode folder's name says was entered (the iPad language study appends it).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Entered {
    /// Nothing appended (an ordinary task evaluation).
    NotRecorded,
    /// The digits pressed, in order.
    Digits(String),
    /// `_no_password_input`: no digit was pressed.
    NoInput,
}

/// One `episode_XX_{success|failure}[...]` folder.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct EpisodeFolder {
    /// The episode number XX.
    pub index: u32,
    /// Whether the evaluator judged the episode a success.
    pub success: bool,
    /// What the name says was entered.
    pub entered: Entered,
    /// Where each subtask ended, from the folder's `episode.json` (`dexjoco-data eval`'s
    /// record); `None` without one (the reference client writes none).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub subtasks: Option<Vec<dexjoco_core::SubtaskSpan>>,
}

impl EpisodeFolder {
    /// Parses a folder name; `None` when it is not an episode folder.
    pub fn parse(name: &str) -> Option<Self> {
        let rest = name.strip_prefix("episode_")?;
        let (index, rest) = rest.split_once('_')?;
        if index.is_empty() || !index.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        let index = index.parse().ok()?;
        let (outcome, suffix) = match rest.split_once('_') {
            Some((o, s)) => (o, Some(s)),
            None => (rest, None),
        };
        let success = match outcome {
            "success" => true,
            "failure" => false,
            _ => return None,
        };
        let entered = match suffix {
            None => Entered::NotRecorded,
            Some("no_password_input") => Entered::NoInput,
            // The reference client joins the digits pressed on each step with `_`
            // (`1_2_3`: three presses): the entry is their concatenation.
            Some(d)
                if d.split('_')
                    .all(|g| !g.is_empty() && g.bytes().all(|b| b.is_ascii_digit())) =>
            {
                Entered::Digits(d.replace('_', ""))
            }
            Some(_) => return None,
        };
        Some(Self {
            index,
            success,
            entered,
            subtasks: None,
        })
    }

    /// The subtask ends an episode folder's record (`episode.json`) holds, when it has a
    /// readable one that records them.
    fn read_subtasks(dir: &Path) -> Option<Vec<dexjoco_core::SubtaskSpan>> {
        #[derive(Deserialize)]
        struct Record {
            subtasks: Option<Vec<dexjoco_core::SubtaskSpan>>,
        }
        let bytes = fs_err::read(dir.join(EPISODE_RECORD)).ok()?;
        serde_json::from_slice::<Record>(&bytes).ok()?.subtasks
    }
}

/// The record `dexjoco-data eval` writes in each episode folder.
pub const EPISODE_RECORD: &str = "episode.json";

/// The parts of a run folder name `<task>[_rand_<x>]_seed<s>`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RunName {
    /// Task id, e.g. `click_mouse`.
    pub task: String,
    /// `rand_obj` when the name has no `_rand_<x>` part, else `rand_<x>` (e.g. `rand_full`).
    pub regime: String,
    /// Evaluation seed.
    pub seed: u32,
}

impl RunName {
    /// Parses a folder name; `None` when it does not end in `_seed<digits>`.
    pub fn parse(name: &str) -> Option<Self> {
        let (head, seed) = name.rsplit_once("_seed")?;
        if head.is_empty() || seed.is_empty() || !seed.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        let seed = seed.parse().ok()?;
        let (task, regime) = match head.rfind("_rand_") {
            Some(at) if at > 0 => (&head[..at], head[at + 1..].to_string()),
            _ => (head, DEFAULT_REGIME.to_string()),
        };
        Some(Self {
            task: task.to_string(),
            regime,
            seed,
        })
    }
}

impl RunName {
    /// The run of an `eval` output folder of any name, from its record (`eval_run.json`:
    /// the task, the seed, `--rand-full`); `None` without one.
    pub fn of_record(dir: &Path) -> Option<Self> {
        let bytes = fs_err::read(dir.join(RUN_RECORD)).ok()?;
        let record: serde_json::Value = serde_json::from_slice(&bytes).ok()?;
        let config = record.get("config")?;
        let options = config.get("options")?;
        let full = options.get("rand_full")?.as_bool()?;
        Some(Self {
            task: config.get("task")?.get("task")?.as_str()?.to_owned(),
            regime: if full { "rand_full" } else { DEFAULT_REGIME }.to_owned(),
            seed: u32::try_from(options.get("seed")?.as_u64()?).ok()?,
        })
    }
}

/// The record `dexjoco-data eval` writes in each run folder.
pub const RUN_RECORD: &str = "eval_run.json";

/// The marker file `success_rate_<n>_<episodes>.txt`.
///
/// `<n>` is read as the number of successful episodes when it is a whole number (it must
/// then be at most `<episodes>`), and as the fraction of successful episodes, in [0, 1],
/// when it has a decimal point (`1.0` is every episode; a decimal above 1 is refused
/// rather than guessed to be a percentage).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Marker {
    /// Success rate in [0, 1].
    pub rate: f64,
    /// Episodes evaluated.
    pub episodes: u32,
}

impl Marker {
    /// Parses a file name: `None` when it is not a marker, an error when it is one with
    /// impossible numbers.
    pub fn parse(name: &str, path: &Path) -> Option<Result<Self, StatsError>> {
        let rest = name.strip_prefix("success_rate_")?.strip_suffix(".txt")?;
        let (n, episodes) = rest.rsplit_once('_')?;
        let episodes: u32 = episodes.parse().ok()?;
        let bad = |why: &str| {
            Some(Err(StatsError::invalid(
                path,
                format!("marker file: {why}"),
            )))
        };
        if episodes == 0 {
            return bad("0 episodes");
        }
        let rate = if n.contains('.') {
            let v: f64 = match n.parse() {
                Ok(v) => v,
                Err(_) => return bad(&format!("'{n}' is not a number")),
            };
            if !(0.0..=1.0).contains(&v) {
                return bad(&format!(
                    "success rate {n} is not a fraction in [0, 1] (a decimal is the fraction of successful episodes, e.g. 0.82; a whole number their count, e.g. 41)"
                ));
            }
            v
        } else {
            let k: u32 = match n.parse() {
                Ok(k) => k,
                Err(_) => return bad(&format!("'{n}' is not a number")),
            };
            if k > episodes {
                return bad(&format!("{k} successes out of {episodes} episodes"));
            }
            f64::from(k) / f64::from(episodes)
        };
        Some(Ok(Self { rate, episodes }))
    }
}

/// One evaluation run: a `<task>[_rand_<x>]_seed<s>` folder and what it holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Run {
    /// The folder.
    pub dir: PathBuf,
    /// The folder, relative to the searched root.
    pub relative: PathBuf,
    /// What its name says.
    pub name: RunName,
    /// Its episode folders, by episode number.
    pub episodes: Vec<EpisodeFolder>,
    /// Its marker file, when present.
    pub marker: Option<Marker>,
}

impl Run {
    /// The folders between the searched root and the run, joined by `/` (`""` when the
    /// run sits directly in the root): what names its policy or its config.
    pub fn parents(&self) -> String {
        self.relative
            .parent()
            .unwrap_or(Path::new(""))
            .components()
            .map(|c| c.as_os_str().to_string_lossy())
            .collect::<Vec<_>>()
            .join("/")
    }

    /// Success rate in [0, 1] and episode count: from the marker file when present,
    /// else from the episode folders. `None` when it has neither.
    pub fn success_rate(&self) -> Option<(f64, u32)> {
        if let Some(m) = self.marker {
            return Some((m.rate, m.episodes));
        }
        let n = self.episodes.len() as u32;
        (n > 0).then(|| {
            let k = self.episodes.iter().filter(|e| e.success).count() as f64;
            (k / f64::from(n), n)
        })
    }

    /// Why the marker file and the episode folders disagree, when they do: which of them
    /// is right cannot be told, so the run is left out, named.
    pub fn marker_mismatch(&self) -> Option<String> {
        let m = self.marker?;
        if self.episodes.is_empty() {
            return None;
        }
        let n = self.episodes.len() as u32;
        let k = self.episodes.iter().filter(|e| e.success).count() as f64;
        let folders = k / f64::from(n);
        ((m.episodes != n) || (m.rate - folders).abs() > 1e-9).then(|| {
            format!(
                "the marker file says {:.1}% of {} episodes, the episode folders {:.1}% of {n}: \
                 remove the marker or the episode folders that are not this run's, and read again",
                100.0 * m.rate,
                m.episodes,
                100.0 * folders
            )
        })
    }
}

fn sorted_entries(dir: &Path) -> Result<Vec<(String, PathBuf, bool)>, StatsError> {
    let mut out = Vec::new();
    for entry in fs_err::read_dir(dir)? {
        let entry = entry?;
        let path = entry.path();
        let is_dir = fs_err::metadata(&path)?.is_dir();
        let name = entry.file_name().to_string_lossy().into_owned();
        out.push((name, path, is_dir));
    }
    out.sort();
    Ok(out)
}

/// Reads one run folder: its episode folders and marker file.
fn read_run(dir: &Path, root: &Path, name: RunName) -> Result<Run, StatsError> {
    let mut episodes: Vec<EpisodeFolder> = Vec::new();
    let mut marker = None;
    for (entry, path, is_dir) in sorted_entries(dir)? {
        if is_dir {
            match EpisodeFolder::parse(&entry) {
                Some(mut e) => {
                    e.subtasks = EpisodeFolder::read_subtasks(&path);
                    if let Some(other) = episodes.iter().find(|o| o.index == e.index) {
                        return Err(StatsError::invalid(
                            &path,
                            format!(
                                "episode {} appears twice in the run (also as {} )",
                                e.index,
                                if other.success {
                                    "a success"
                                } else {
                                    "a failure"
                                }
                            ),
                        ));
                    }
                    episodes.push(e);
                }
                None if entry.starts_with("episode_") => {
                    return Err(StatsError::invalid(
                        &path,
                        "not an episode folder name: expected episode_<n>_{success|failure}[_<digits>|_no_password_input]",
                    ));
                }
                None => tracing::debug!("ignoring {}", path.display()),
            }
        } else if let Some(m) = Marker::parse(&entry, &path) {
            let m = m?;
            if marker.replace(m).is_some() {
                return Err(StatsError::invalid(
                    dir,
                    "more than one success_rate_*.txt marker file",
                ));
            }
        }
    }
    episodes.sort_by_key(|e| e.index);
    Ok(Run {
        dir: dir.to_path_buf(),
        relative: dir.strip_prefix(root).unwrap_or(dir).to_path_buf(),
        name,
        episodes,
        marker,
    })
}

/// A run folder that could not be read (a bad marker file, a misnamed episode folder, an
/// episode number given twice): left out of the analysis and named, never stopping it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LeftOutRun {
    /// The run folder.
    pub path: PathBuf,
    /// Why it was left out.
    pub reason: String,
}

/// `; left out: <folder> (<reason>)...` for a message, or nothing.
pub(crate) fn left_out_note(left_out: &[LeftOutRun]) -> String {
    if left_out.is_empty() {
        return String::new();
    }
    let list: Vec<String> = left_out
        .iter()
        .map(|l| format!("'{}' ({})", l.path.display(), l.reason))
        .collect();
    format!("; left out: {}", list.join(", "))
}

/// Finds every run folder under `root` (the root itself included, under any name when it
/// holds `eval`'s record): a folder named `<task>[_rand_<x>]_seed<s>` that holds episode
/// folders or a marker file. Sorted by path. A run folder that cannot be read, or whose
/// marker disagrees with its episode folders, is left out and returned with its reason
/// (one bad folder is one bad folder); a root that cannot be listed is an error.
pub fn find_runs(root: &Path) -> Result<(Vec<Run>, Vec<LeftOutRun>), StatsError> {
    if !root.is_dir() {
        return Err(StatsError::invalid(root, "not a folder"));
    }
    let mut runs = Vec::new();
    let mut left_out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        let name = dir.file_name().map(|n| n.to_string_lossy().into_owned());
        let run_name = match name.as_deref().and_then(RunName::parse) {
            Some(n) => Some(n),
            // The root may be one run's folder of any name (`eval --output DIR`).
            None if dir == root => RunName::of_record(&dir),
            None => None,
        };
        if let Some(run_name) = run_name {
            match read_run(&dir, root, run_name) {
                Ok(run) if run.marker_mismatch().is_some() => {
                    let reason = run.marker_mismatch().unwrap_or_default();
                    left_out.push(LeftOutRun { path: dir, reason });
                    continue;
                }
                Ok(run) if !run.episodes.is_empty() || run.marker.is_some() => {
                    runs.push(run);
                    continue;
                }
                Ok(_) => {}
                Err(e) => {
                    left_out.push(LeftOutRun {
                        path: dir.clone(),
                        reason: e.to_string(),
                    });
                    continue;
                }
            }
        }
        for (entry, path, is_dir) in sorted_entries(&dir)?.into_iter().rev() {
            if is_dir && !entry.starts_with('.') && EpisodeFolder::parse(&entry).is_none() {
                stack.push(path);
            }
        }
    }
    runs.sort_by(|a, b| a.dir.cmp(&b.dir));
    left_out.sort_by(|a, b| a.path.cmp(&b.path));
    Ok((runs, left_out))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn episode_folder_names() {
        let e = EpisodeFolder::parse("episode_07_failure_23").unwrap();
        assert_eq!((e.index, e.success), (7, false));
        assert_eq!(e.entered, Entered::Digits("23".into()));
        // Digits pressed on separate steps, as the reference client names them.
        let e = EpisodeFolder::parse("episode_07_success_1_2_3").unwrap();
        assert_eq!(e.entered, Entered::Digits("123".into()));
        assert_eq!(EpisodeFolder::parse("episode_01_failure_1__2"), None);
        let e = EpisodeFolder::parse("episode_12_success").unwrap();
        assert!(e.success);
        assert_eq!(e.entered, Entered::NotRecorded);
        let e = EpisodeFolder::parse("episode_3_failure_no_password_input").unwrap();
        assert_eq!(e.entered, Entered::NoInput);
        assert_eq!(EpisodeFolder::parse("episode_x_success"), None);
        assert_eq!(EpisodeFolder::parse("episode_01_maybe"), None);
        assert_eq!(EpisodeFolder::parse("episode_01_failure_abc"), None);
        assert_eq!(EpisodeFolder::parse("videos"), None);
    }

    #[test]
    fn run_folder_names() {
        let r = RunName::parse("bimanual_unlock_ipad_rand_full_seed2").unwrap();
        assert_eq!(
            (r.task.as_str(), r.regime.as_str(), r.seed),
            ("bimanual_unlock_ipad", "rand_full", 2)
        );
        let r = RunName::parse("click_mouse_seed0").unwrap();
        assert_eq!(
            (r.task.as_str(), r.regime.as_str()),
            ("click_mouse", "rand_obj")
        );
        assert_eq!(RunName::parse("click_mouse_seedx"), None);
        assert_eq!(RunName::parse("click_mouse"), None);
    }

    #[test]
    fn marker_names() {
        let p = Path::new("m");
        let m = Marker::parse("success_rate_41_50.txt", p).unwrap().unwrap();
        assert!((m.rate - 0.82).abs() < 1e-15 && m.episodes == 50);
        let m = Marker::parse("success_rate_0.82_50.txt", p)
            .unwrap()
            .unwrap();
        assert!((m.rate - 0.82).abs() < 1e-15);
        // One rule for decimals: a fraction in [0, 1], never a percentage.
        let m = Marker::parse("success_rate_1.0_50.txt", p)
            .unwrap()
            .unwrap();
        assert!((m.rate - 1.0).abs() < 1e-15);
        for above_one in ["1.5", "82.0"] {
            let err = Marker::parse(&format!("success_rate_{above_one}_50.txt"), p)
                .unwrap()
                .unwrap_err()
                .to_string();
            assert!(err.contains("not a fraction in [0, 1]"), "{err}");
        }
        assert!(Marker::parse("success_rate_51_50.txt", p).unwrap().is_err());
        assert!(Marker::parse("notes.txt", p).is_none());
    }
}
