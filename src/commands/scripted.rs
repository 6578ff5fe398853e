//! `dexjoco-data scripted`: scripted demonstrations of a task from random resets (the
//! task's placement ranges and table offset, drawn from `--seed`), planned on privileged
//! state, written in the DexJoCo raw layout; plans that do not succeed are counted and
//! not written.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use dexjoco_sim::scripted::{self, Variant};
use dexjoco_sim::{SceneSource, TaskEnv, load_task_scene};
use rand::{Rng, SeedableRng};

use crate::cli::GlobalArgs;
use crate::exit::{CliError, ExitStatus};

/// `scripted` options.
#[derive(Debug, Args)]
#[command(after_help = "\
Writes OUT/<task>/episode_NNNNNN (action, state, timestamps; no videos), numbered in the
order the successful plans were made. The same --seed, task and scene give identical
files. Exit code 3: some plans did not succeed (not written); 1: none did.")]
pub struct ScriptedArgs {
    /// Task id, e.g. pinch_tongs.
    #[arg(long)]
    pub task: String,
    /// Random resets to plan from.
    #[arg(long, default_value_t = 1)]
    pub episodes: usize,
    /// Scene pack folder (e.g. the DexJoCo reference xmls/); default: built-in scenes.
    #[arg(long)]
    pub scene_dir: Option<PathBuf>,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs `scripted`.
pub fn run(global: &GlobalArgs, args: &ScriptedArgs) -> anyhow::Result<ExitStatus> {
    // An unknown task is a usage error (exit 2), as in every command.
    let spec = crate::settings::known_task(dexjoco_core::TaskSet::builtin(), &args.task)?;
    if !scripted::PLANNED_TASKS.contains(&spec.id.as_str()) {
        return Err(CliError {
            message: format!("no scripted planner for '{}'", spec.id),
            hint: Some(format!(
                "tasks with a planner: {}",
                scripted::PLANNED_TASKS.join(", ")
            )),
            status: ExitStatus::Failure,
        }
        .into());
    }
    let scene = load_task_scene(&SceneSource::from_option(args.scene_dir.clone()), spec)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(global.seed);
    let task_dir = args.out.join(&spec.id);
    let pb = crate::progress::bar(args.episodes as u64, "scripted", global.quiet);
    let mut written = 0usize;
    for k in 0..args.episodes {
        let s0 = TaskEnv::sample_initial_state(&scene, spec, &mut || rng.random::<f64>())?;
        let id = format!("{}_scripted_seed{}_{k}", spec.id, global.seed);
        let plan = scripted::plan(&scene, spec, &s0, &id, Variant::Demo)?;
        match plan.success_at {
            Some(step) => {
                let dir = task_dir.join(format!("episode_{written:06}"));
                if dir.exists() {
                    fs_err::remove_dir_all(&dir)?;
                }
                dexjoco_formats::raw::write_replay_zarr(&dir, &plan.episode)
                    .with_context(|| format!("writing '{}'", dir.display()))?;
                let line = format!("reset {k}: success at step {step} -> {}", dir.display());
                if !global.quiet {
                    pb.suspend(|| errln!("{line}"));
                }
                written += 1;
            }
            None => {
                let line = format!(
                    "reset {k}: no success in {} steps{} (not written)",
                    plan.episode.len(),
                    if plan.failed { ", task failed" } else { "" }
                );
                if !global.quiet {
                    pb.suspend(|| errln!("{line}"));
                }
            }
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    let pct = 100.0 * written as f64 / args.episodes.max(1) as f64;
    errln!(
        "{}: {written}/{} plans succeeded ({pct:.0}%), written to {}",
        spec.id,
        args.episodes,
        task_dir.display()
    );
    Ok(if written == args.episodes {
        ExitStatus::Success
    } else if written > 0 {
        ExitStatus::Partial
    } else {
        ExitStatus::Failure
    })
}
