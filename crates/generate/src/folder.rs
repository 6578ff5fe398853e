//! A generation run's folder: the settings file every run into it must match, the
//! attempts' records (the resume log), committing an attempt, the surplus a larger
//! earlier run (or shards running past the end) left beyond this run's end, and what a
//! killed run left behind.

use std::collections::BTreeMap;
use std::path::Path;

use dexjoco_core::{Shard, TaskSpec};
use dexjoco_formats::raw::RawFolder;
use dexjoco_formats::{EpisodeContainer, EpisodeMeta, write_atomic};
use dexjoco_sim::SceneSource;
use serde::Serialize;
use sha2::{Digest, Sha256};

use crate::attempt::Attempt;
use crate::error::GenerateError;
use crate::record::{AttemptRecord, GENERATE_RECORD, GenerateConfig, SETTINGS_FILE};
use crate::source::SourceDemo;

/// Records of finished attempts.
const ATTEMPTS: &str = ".attempts";
/// Failed attempts' episodes (`keep_failed`).
const FAILED: &str = ".failed";
/// Attempts set aside beyond a run's end, as they were (records, episodes).
const SURPLUS: &str = ".surplus";
/// Episodes being written.
const STAGING: &str = ".staging";

/// Hex SHA-256 of a serializable value's JSON.
fn sha256_json(v: &impl Serialize) -> String {
    let bytes = serde_json::to_vec(v).expect("serializable");
    format!("{:x}", Sha256::digest(bytes))
}

/// The settings that decide a run's bytes: the scene named and, by content, every file
/// it loads (a resume after a scene file changed would mix episodes of two scenes).
pub(crate) fn settings(
    config: &GenerateConfig,
    spec: &TaskSpec,
    sources: &[SourceDemo],
) -> Result<serde_json::Value, GenerateError> {
    let label = match &config.scene {
        SceneSource::BuiltIn => "built-in".to_owned(),
        SceneSource::Dir(d) => format!("dir:{}", dexjoco_formats::fs::resolve(d).display()),
    };
    let hashes = dexjoco_sim::scene_files::scene_hash(&config.scene, spec)?;
    Ok(serde_json::json!({
        "format": "dexjoco-data/generate-settings",
        "version": 1,
        "task": spec.id,
        "spec": format!("sha256:{}", sha256_json(spec)),
        "scene": label,
        "scene_content": {"scene": hashes.scene, "files": hashes.files},
        "extend_steps": config.extend_steps,
        "seed": config.seed,
        "options": config.options,
        "sources": sources.iter().map(|s| [s.id.clone(), s.sha256.clone()]).collect::<Vec<_>>(),
    }))
}

/// Writes the settings file, or checks an earlier run's against it; with `overwrite`, an
/// earlier run's folder of other settings is emptied first. A folder that holds files
/// but no settings file is not a generate run's, and is never written into.
pub(crate) fn check_settings(
    out: &Path,
    want: &serde_json::Value,
    overwrite: bool,
) -> Result<(), GenerateError> {
    let path = out.join(SETTINGS_FILE);
    let bytes = serde_json::to_vec_pretty(want).expect("serializable");
    let old = match fs_err::read(&path) {
        Ok(old) => Some(serde_json::from_slice::<serde_json::Value>(&old).unwrap_or_default()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(e) => return Err(e.into()),
    };
    let Some(old) = old else {
        let foreign = fs_err::read_dir(out)?
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            // Hidden entries are runs' work in progress (locks, staging, a settings file
            // another shard is writing), never another program's output.
            .find(|n| !n.starts_with('.') && n != SETTINGS_FILE);
        if let Some(name) = foreign {
            return Err(GenerateError::Foreign {
                path: out.to_path_buf(),
                name,
            });
        }
        return Ok(write_atomic(&path, &bytes)?);
    };
    let keys = want.as_object().expect("an object");
    let Some((k, _)) = keys.iter().find(|(k, v)| old.get(k.as_str()) != Some(v)) else {
        return Ok(());
    };
    if !overwrite {
        return Err(GenerateError::OtherRun {
            path: out.to_path_buf(),
            difference: format!("{k} differs from {}", path.display()),
        });
    }
    for e in fs_err::read_dir(out)?.flatten() {
        if e.file_name()
            .to_string_lossy()
            .starts_with(dexjoco_formats::lock::LOCK_FILE)
        {
            continue;
        }
        if e.file_type()?.is_dir() {
            fs_err::remove_dir_all(e.path())?;
        } else {
            fs_err::remove_file(e.path())?;
        }
    }
    fs_err::create_dir_all(out.join(ATTEMPTS))?;
    Ok(write_atomic(&path, &bytes)?)
}

fn attempt_name(k: usize) -> String {
    format!("attempt_{k:06}")
}

fn episode_name(k: usize) -> String {
    format!("episode_{k:06}")
}

/// A record of the resume log that is not trusted, and why: the attempt is redone.
#[derive(Debug, Clone)]
pub(crate) struct Untrusted {
    /// The record file.
    pub(crate) file: std::path::PathBuf,
    /// The attempt its name says.
    pub(crate) attempt: Option<usize>,
    /// Why it is not trusted.
    pub(crate) why: String,
}

/// The resume log of a folder: the records of finished attempts that check out, by index,
/// and those that do not.
#[derive(Debug, Default)]
pub(crate) struct Finished {
    pub(crate) done: BTreeMap<usize, AttemptRecord>,
    pub(crate) untrusted: Vec<Untrusted>,
}

/// The records of the attempts earlier runs finished, each checked before it is trusted
/// (a record decides what a resumed run skips and what its report lists): it parses,
/// its file's name is its attempt, its seed is the run's, its reset has the task's state
/// width, its steps, success step and subtask spans agree, and a success's episode folder
/// is there and complete (its record the same, its `replay.zarr` of that many steps).
pub(crate) fn finished(out: &Path, spec: &TaskSpec, seed: u64) -> Result<Finished, GenerateError> {
    let mut log = Finished::default();
    let dir = out.join(ATTEMPTS);
    let Ok(entries) = fs_err::read_dir(&dir) else {
        return Ok(log);
    };
    let mut entries: Vec<_> = entries.flatten().map(|e| e.path()).collect();
    entries.sort();
    for path in entries {
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        // Hidden files are a killed writer's temporary files, cleaned up elsewhere.
        if name.starts_with('.') {
            continue;
        }
        let attempt = name
            .strip_prefix("attempt_")
            .and_then(|n| n.strip_suffix(".json"))
            .and_then(|n| n.parse::<usize>().ok());
        match check_record(out, &path, attempt, spec, seed) {
            Ok(r) => {
                log.done.insert(r.attempt, r);
            }
            Err(why) => log.untrusted.push(Untrusted {
                file: path,
                attempt,
                why,
            }),
        }
    }
    Ok(log)
}

/// The largest record read (a record holds a reset and a few spans).
const MAX_RECORD_BYTES: u64 = 16 << 20;

/// The record at `path` (named for attempt `attempt`), or why it is not trusted.
fn check_record(
    out: &Path,
    path: &Path,
    attempt: Option<usize>,
    spec: &TaskSpec,
    seed: u64,
) -> Result<AttemptRecord, String> {
    let r = read_record(path)?;
    let Some(k) = attempt.filter(|k| *k == r.attempt) else {
        return Err(format!(
            "it records attempt {}, not the one its name says",
            r.attempt
        ));
    };
    if r.seed != seed {
        return Err(format!("its seed {} is not the run's {seed}", r.seed));
    }
    let width = spec.state_layout().width();
    // Positions in metres, quaternions, joint angles: a value past 1000 is no state.
    let plausible = |x: &f64| x.is_finite() && x.abs() <= 1e3;
    if r.reset.len() != width || !r.reset.iter().all(plausible) {
        return Err(format!(
            "its reset holds {} values (each within 1000: {}), the task's state has {width}",
            r.reset.len(),
            r.reset.iter().all(plausible)
        ));
    }
    let spans_end = r
        .subtasks
        .iter()
        .flat_map(|s| [s.start, s.end])
        .flatten()
        .max();
    if r.steps == 0 || spans_end.is_some_and(|e| e > r.steps) {
        return Err(format!(
            "its {} steps do not hold its subtask spans",
            r.steps
        ));
    }
    match (r.success, r.success_step, &r.failure) {
        (true, Some(s), _) if s <= r.steps => {}
        (false, None, Some(_)) => {}
        _ => {
            return Err(format!(
                "its verdict (success {}, success step {:?}, failure {}) does not hold together",
                r.success,
                r.success_step,
                if r.failure.is_some() { "given" } else { "none" }
            ));
        }
    }
    if r.success {
        let episode = out.join(episode_name(k));
        let mine = read_record(&episode.join(GENERATE_RECORD)).map_err(|e| {
            format!(
                "its episode '{}' is missing or incomplete: {e}",
                episode.display()
            )
        })?;
        if mine != r {
            return Err(format!(
                "its episode '{}' records another attempt",
                episode.display()
            ));
        }
        let rows = zarr_rows(&episode.join("replay.zarr/data/action/.zarray"))
            .map_err(|e| format!("its episode '{}' is incomplete: {e}", episode.display()))?;
        if rows != r.steps as u64 {
            return Err(format!(
                "its episode '{}' holds {rows} steps, the record {}",
                episode.display(),
                r.steps
            ));
        }
    }
    Ok(r)
}

/// An attempt record read from `path` (bounded), or why not.
fn read_record(path: &Path) -> Result<AttemptRecord, String> {
    use std::io::Read;
    let mut bytes = Vec::new();
    fs_err::File::open(path)
        .and_then(|f| f.take(MAX_RECORD_BYTES + 1).read_to_end(&mut bytes))
        .map_err(|e| e.to_string())?;
    if bytes.len() as u64 > MAX_RECORD_BYTES {
        return Err(format!("it is larger than {} MB", MAX_RECORD_BYTES >> 20));
    }
    serde_json::from_slice(&bytes).map_err(|e| format!("it is no attempt record: {e}"))
}

/// The first dimension of a Zarr v2 array (its `.zarray`'s `shape[0]`).
fn zarr_rows(zarray: &Path) -> Result<u64, String> {
    let text = fs_err::read(zarray).map_err(|e| e.to_string())?;
    let v: serde_json::Value = serde_json::from_slice(&text).map_err(|e| e.to_string())?;
    v["shape"][0]
        .as_u64()
        .ok_or_else(|| format!("'{}' has no shape", zarray.display()))
}

/// Forgets the untrusted records of `log` (each named in a warning): the record and the
/// attempt's episode folders are removed, so the attempt is made again.
pub(crate) fn forget(out: &Path, log: &Finished) -> Result<(), GenerateError> {
    for u in &log.untrusted {
        tracing::warn!(
            "'{}' is not trusted ({}): attempt {} is made again",
            u.file.display(),
            u.why,
            u.attempt.map_or_else(|| "?".into(), |k| k.to_string())
        );
        fs_err::remove_file(&u.file)?;
        if let Some(k) = u.attempt.filter(|k| !log.done.contains_key(k)) {
            for rel in places(k).into_iter().skip(1) {
                let p = out.join(rel);
                if p.is_dir() {
                    fs_err::remove_dir_all(&p)?;
                }
            }
        }
    }
    Ok(())
}

/// Commits one attempt: a success's episode folder (staged, renamed into place), a
/// failure's folder under `.failed/` with `keep_failed`; then its record, which marks it
/// done.
pub(crate) fn commit(
    out: &Path,
    spec: &TaskSpec,
    a: &Attempt,
    config: &GenerateConfig,
) -> Result<AttemptRecord, GenerateError> {
    let record = AttemptRecord::of(a, config.seed);
    let json = serde_json::to_vec_pretty(&record).expect("serializable");
    let folder = if record.success {
        Some(out.join(episode_name(a.index)))
    } else if config.keep_failed {
        Some(out.join(FAILED).join(attempt_name(a.index)))
    } else {
        None
    };
    if let Some(folder) = folder {
        let staging = out.join(STAGING).join(attempt_name(a.index));
        if staging.exists() {
            fs_err::remove_dir_all(&staging)?;
        }
        RawFolder.write(&staging, &a.planned.episode, spec, &EpisodeMeta::default())?;
        write_atomic(&staging.join(GENERATE_RECORD), &json)?;
        if folder.exists() {
            fs_err::remove_dir_all(&folder)?;
        }
        fs_err::create_dir_all(folder.parent().expect("in out"))?;
        fs_err::rename(&staging, &folder)?;
    }
    write_atomic(
        &out.join(ATTEMPTS)
            .join(format!("{}.json", attempt_name(a.index))),
        &json,
    )?;
    Ok(record)
}

/// The places attempt `k` may occupy in the folder, relative to it: its record, its
/// episode (a success) and its failed episode (`keep_failed`).
fn places(k: usize) -> [std::path::PathBuf; 3] {
    [
        Path::new(ATTEMPTS).join(format!("{}.json", attempt_name(k))),
        Path::new(&episode_name(k)).to_path_buf(),
        Path::new(FAILED).join(attempt_name(k)),
    ]
}

/// Moves what attempt `k` left from under `from` to the same place under `to`.
fn move_attempt(from: &Path, to: &Path, k: usize) -> Result<(), GenerateError> {
    for rel in places(k) {
        let (a, b) = (from.join(&rel), to.join(&rel));
        if a.exists() {
            if b.exists() {
                fs_err::remove_dir_all(&b).or_else(|_| fs_err::remove_file(&b))?;
            }
            fs_err::create_dir_all(b.parent().expect("in the folder"))?;
            fs_err::rename(&a, &b)?;
        }
    }
    Ok(())
}

/// Puts back the attempts an earlier run set aside (before a run reads the records).
pub(crate) fn restore_surplus(out: &Path, spec: &TaskSpec, seed: u64) -> Result<(), GenerateError> {
    let surplus = out.join(SURPLUS);
    // Untrusted ones are left there, removed with the rest of the surplus.
    for k in finished(&surplus, spec, seed)?.done.into_keys() {
        move_attempt(&surplus, out, k)?;
    }
    if surplus.exists() {
        fs_err::remove_dir_all(&surplus)?;
    }
    Ok(())
}

/// Sets aside the attempts past `end` (exclusive), so that the folder holds what a run
/// that stopped at `end` writes.
pub(crate) fn set_aside(
    out: &Path,
    done: &mut BTreeMap<usize, AttemptRecord>,
    end: usize,
) -> Result<(), GenerateError> {
    let past: Vec<usize> = done.range(end..).map(|(k, _)| *k).collect();
    for k in past {
        move_attempt(out, &out.join(SURPLUS), k)?;
        done.remove(&k);
    }
    Ok(())
}

/// Removes what a killed run left: its staged episodes and half-written files. A shard
/// removes only its own staged attempts (the others' may be in progress) and leaves the
/// half-written files to the unsharded run that finalizes.
pub(crate) fn clean_up(out: &Path, shard: Option<Shard>) -> Result<(), GenerateError> {
    let staging = out.join(STAGING);
    let Some(shard) = shard else {
        if staging.exists() {
            fs_err::remove_dir_all(&staging)?;
        }
        for dir in [out.to_path_buf(), out.join(ATTEMPTS)] {
            dexjoco_formats::fs::remove_partial_files(&dir)?;
        }
        return Ok(());
    };
    let Ok(entries) = fs_err::read_dir(&staging) else {
        return Ok(());
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        let index = name
            .strip_prefix("attempt_")
            .and_then(|n| n.parse::<usize>().ok());
        if index.is_some_and(|k| k % shard.count == shard.index) {
            fs_err::remove_dir_all(e.path())?;
        }
    }
    Ok(())
}

/// Removes the empty staging folder at the end of an unsharded run.
pub(crate) fn remove_staging(out: &Path) -> Result<(), GenerateError> {
    let staging = out.join(STAGING);
    if staging.exists() {
        fs_err::remove_dir_all(&staging)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};

    use dexjoco_testkit::hostile::{apply_bytes, apply_json, byte_edits, json_edits, run_cases};
    use proptest::prelude::*;

    use super::*;

    /// A folder holding attempt 3's record and, for a success, its episode's record and
    /// the `.zarray` of its actions.
    fn folder(root: &Path, record: &[u8], episode: Option<(&[u8], u64)>) {
        fs_err::create_dir_all(root.join(ATTEMPTS)).unwrap();
        fs_err::write(root.join(ATTEMPTS).join("attempt_000003.json"), record).unwrap();
        if let Some((json, rows)) = episode {
            let data = root.join(episode_name(3)).join("replay.zarr/data/action");
            fs_err::create_dir_all(&data).unwrap();
            fs_err::write(root.join(episode_name(3)).join(GENERATE_RECORD), json).unwrap();
            let zarray = serde_json::json!({"shape": [rows, 23]});
            fs_err::write(data.join(".zarray"), zarray.to_string()).unwrap();
        }
    }

    fn valid(spec: &TaskSpec) -> serde_json::Value {
        serde_json::json!({
            "written_by": "dexjoco-data generate",
            "attempt": 3,
            "seed": 11,
            "success": true,
            "success_step": 99,
            "steps": 100,
            "failure": null,
            "subtasks": [{"id": "a", "text": "", "start": 0, "end": 60}],
            "provenance": [],
            "reset": vec![0.5; spec.state_layout().width()],
        })
    }

    /// Mutated records (and episode folders that lack, or disagree with, them): reading
    /// the resume log never panics, and every record it trusts is one the figure, the
    /// report and the count can use (the task's reset width, a whole episode folder).
    #[test]
    fn hostile_resume_logs_are_checked_never_a_panic() {
        static TRUSTED: AtomicUsize = AtomicUsize::new(0);
        static REDONE: AtomicUsize = AtomicUsize::new(0);
        let spec = dexjoco_core::TaskSpec::builtin("click_mouse").unwrap();
        let doc = valid(spec);
        let tmp = Arc::new(tempfile::tempdir().unwrap());
        let case = Arc::new(AtomicUsize::new(0));
        let strategy = (
            json_edits(3),
            prop::option::weighted(0.2, byte_edits(3)),
            prop::option::weighted(
                0.8,
                (
                    any::<bool>(),
                    prop_oneof![3 => Just(100u64), 1 => 98u64..102],
                ),
            ),
        );
        let took = run_cases(
            "resume log",
            800,
            strategy,
            move |(edits, bytes, episode)| {
                let text = apply_json(&doc, &edits).to_string();
                let record = match &bytes {
                    Some(e) => apply_bytes(text.as_bytes(), e),
                    None => text.clone().into_bytes(),
                };
                let root = tmp
                    .path()
                    .join(case.fetch_add(1, Ordering::Relaxed).to_string());
                // The episode's record: this one, or the valid one (which may disagree).
                let ep = episode.map(|(same, rows)| {
                    (
                        if same {
                            record.clone()
                        } else {
                            doc.to_string().into_bytes()
                        },
                        rows,
                    )
                });
                folder(&root, &record, ep.as_ref().map(|(j, r)| (j.as_slice(), *r)));
                let log = finished(&root, spec, 11).map_err(|e| e.to_string())?;
                TRUSTED.fetch_add(log.done.len(), Ordering::Relaxed);
                REDONE.fetch_add(log.untrusted.len(), Ordering::Relaxed);
                for r in log.done.values() {
                    if r.reset.len() != spec.state_layout().width() {
                        return Err(format!("a reset of {} values trusted", r.reset.len()));
                    }
                    if r.success
                        && !root
                            .join(episode_name(r.attempt))
                            .join("replay.zarr")
                            .is_dir()
                    {
                        return Err("a success without its episode trusted".into());
                    }
                }
                let records: Vec<&AttemptRecord> = log.done.values().collect();
                if !records.is_empty() {
                    crate::figure::write_pose_figure(&root.join("poses.png"), spec, &[], &records)
                        .map_err(|e| e.to_string())?;
                }
                forget(&root, &log).map_err(|e| e.to_string())?;
                fs_err::remove_dir_all(&root).unwrap();
                Ok(())
            },
        );
        assert!(took.as_secs() < 120, "{took:?}");
        let trusted = TRUSTED.load(Ordering::Relaxed);
        assert!(trusted > 20, "some records are trusted: {trusted}");
        assert!(REDONE.load(Ordering::Relaxed) > 100, "some are not");
    }

    /// The cases that crashed or fooled a resumed run: a record with an empty reset (the
    /// figure indexed it), a success whose episode folder was deleted (counted as made).
    #[test]
    fn the_records_a_resume_once_trusted_are_redone() {
        let spec = dexjoco_core::TaskSpec::builtin("click_mouse").unwrap();
        let tmp = tempfile::tempdir().unwrap();
        let mut empty = valid(spec);
        empty["reset"] = serde_json::json!([]);
        let text = empty.to_string();
        folder(tmp.path(), text.as_bytes(), Some((text.as_bytes(), 100)));
        let log = finished(tmp.path(), spec, 11).unwrap();
        assert!(log.done.is_empty(), "{:?}", log.done);
        assert!(
            log.untrusted[0].why.contains("reset holds 0 values"),
            "{:?}",
            log.untrusted
        );
        forget(tmp.path(), &log).unwrap();
        assert!(!tmp.path().join(episode_name(3)).exists());
        let gone = tmp.path().join("gone");
        let text = valid(spec).to_string();
        folder(&gone, text.as_bytes(), None);
        let log = finished(&gone, spec, 11).unwrap();
        assert!(
            log.untrusted[0].why.contains("missing or incomplete"),
            "{:?}",
            log.untrusted
        );
    }

    /// A run's settings fingerprint its scene by content: a resume after a file the scene
    /// includes changed is refused, naming it (the path alone once let two scenes' episodes
    /// share a folder).
    #[test]
    fn a_changed_scene_file_refuses_the_resume() {
        let spec = dexjoco_core::TaskSpec::builtin("click_mouse").unwrap();
        let tmp = tempfile::tempdir().unwrap();
        let scenes = tmp.path().join("xmls");
        fs_err::create_dir_all(&scenes).unwrap();
        fs_err::write(
            scenes.join(&spec.scene),
            "<mujoco><include file=\"mouse.xml\"/></mujoco>",
        )
        .unwrap();
        fs_err::write(scenes.join("mouse.xml"), "<mujoco/>").unwrap();
        let config = GenerateConfig {
            out: tmp.path().join("out"),
            seed: 0,
            count: 1,
            max_attempts: 1,
            workers: 1,
            keep_failed: false,
            overwrite: false,
            shard: None,
            options: crate::AttemptOptions::default(),
            scene: SceneSource::Dir(scenes.clone()),
            extend_steps: 0,
        };
        fs_err::create_dir_all(&config.out).unwrap();
        let before = settings(&config, spec, &[]).unwrap();
        check_settings(&config.out, &before, false).unwrap();
        check_settings(&config.out, &before, false).unwrap();
        fs_err::write(scenes.join("mouse.xml"), "<mujoco><!-- moved --></mujoco>").unwrap();
        let after = settings(&config, spec, &[]).unwrap();
        assert_eq!(before["scene"], after["scene"], "the same folder");
        let e = check_settings(&config.out, &after, false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("scene_content"), "{e}");
    }
}
