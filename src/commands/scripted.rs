//! `dexjoco-data scripted`: scripted demonstrations of a task from random resets (the
//! task's placement ranges and table offset, drawn from `--seed`), planned on privileged
//! state, written in the DexJoCo raw layout; plans that do not succeed are counted and
//! not written.

use std::path::Path;

use anyhow::Context;
use dexjoco_formats::fs::StagedDir;
use dexjoco_formats::raw::RawFolder;
use dexjoco_formats::{EpisodeContainer, EpisodeMeta, FormatError};
use dexjoco_scripted::{self as scripted, Variant};
use dexjoco_sim::{TaskEnv, load_task_scene};
use rand::{Rng, SeedableRng};

use crate::exit::{CliError, ExitStatus};
use crate::settings::ScriptedSettings;

/// Runs `scripted`.
pub fn run(settings: ScriptedSettings) -> anyhow::Result<ExitStatus> {
    let ScriptedSettings {
        task: spec,
        episodes,
        scene,
        task_dir,
        overwrite,
        seed,
        quiet,
    } = settings;
    let spec = &spec;
    // Written beside, renamed into place whole when done. Begun first: it puts back a
    // folder a killed run had moved aside, which is then checked like any other.
    let staged = StagedDir::begin(&task_dir)?;
    check_replaceable(&task_dir, overwrite)?;
    let scene = load_task_scene(&scene, spec)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let pb = crate::progress::bar(episodes as u64, "scripted", quiet);
    let mut written = 0usize;
    for k in 0..episodes {
        let s0 = TaskEnv::sample_initial_state(&scene, spec, &mut || rng.random::<f64>())?;
        let id = format!("{}_scripted_seed{}_{k}", spec.id, seed);
        let plan = scripted::plan(&scene, spec, &s0, &id, Variant::Demo)?;
        let line = match plan.success_at {
            Some(step) => {
                let name = format!("episode_{written:06}");
                let dir = staged.path().join(&name);
                RawFolder
                    .write(&dir, &plan.episode, spec, &EpisodeMeta::default())
                    .and_then(|()| write_plan_record(&dir, &plan, seed, k))
                    .with_context(|| format!("writing '{}'", task_dir.join(&name).display()))?;
                written += 1;
                let dir = task_dir.join(&name);
                format!(
                    "reset {k}: success at step {step} ({}) -> {}",
                    subtask_words(&plan.subtasks),
                    dir.display()
                )
            }
            None => format!(
                "reset {k}: no success in {} steps{} (not written)",
                plan.episode.len(),
                if plan.failed { ", task failed" } else { "" }
            ),
        };
        if !quiet {
            pb.suspend(|| errln!("{line}"));
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    if written > 0 {
        staged
            .commit()
            .with_context(|| format!("renaming '{}' into place", task_dir.display()))?;
    }
    let pct = 100.0 * written as f64 / episodes.max(1) as f64;
    errln!(
        "{}: {written}/{episodes} plans succeeded ({pct:.0}%), written to {}",
        spec.id,
        task_dir.display()
    );
    Ok(if written == episodes {
        ExitStatus::Success
    } else if written > 0 {
        ExitStatus::Partial
    } else {
        ExitStatus::Failure
    })
}

/// An earlier run's `<out>/<task>` is replaced only with `--overwrite`, and only when it
/// holds nothing but `episode_*` folders (what scripted writes).
fn check_replaceable(task_dir: &Path, overwrite: bool) -> anyhow::Result<()> {
    if !dexjoco_formats::fs::is_non_empty_dir(task_dir) {
        return Ok(());
    }
    if !overwrite {
        return Err(FormatError::WouldReplace {
            path: task_dir.to_path_buf(),
        }
        .into());
    }
    let foreign = fs_err::read_dir(task_dir)?
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .find(|n| !n.starts_with("episode_"));
    match foreign {
        None => Ok(()),
        Some(name) => Err(CliError {
            message: format!(
                "'{}' holds '{name}', which scripted does not write: it is not replaced",
                task_dir.display()
            ),
            hint: Some("choose another --out".into()),
            status: ExitStatus::Failure,
        }
        .into()),
    }
}

/// The plan's record beside its `replay.zarr` (`plan.json`): the reset it was planned
/// from, the success step and where each subtask ended.
fn write_plan_record(
    dir: &Path,
    plan: &scripted::Planned,
    seed: u64,
    reset: usize,
) -> Result<(), FormatError> {
    let record = serde_json::json!({
        "written_by": "dexjoco-data scripted",
        "seed": seed,
        "reset": reset,
        "success_step": plan.success_at,
        "subtasks": plan.subtasks,
    });
    let bytes = serde_json::to_vec_pretty(&record).expect("serializable");
    dexjoco_formats::write_atomic(&dir.join(dexjoco_formats::raw::PLAN_RECORD), &bytes)
}

/// `grasp_hammer 374, hit_nail 587, drive_nail -`: where each subtask ended.
fn subtask_words(ends: &[dexjoco_core::SubtaskSpan]) -> String {
    ends.iter()
        .map(|e| format!("{} {}", e.id, e.end.map_or("-".into(), |s| s.to_string())))
        .collect::<Vec<_>>()
        .join(", ")
}
