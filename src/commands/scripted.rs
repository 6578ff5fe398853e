//! `dexjoco-data scripted`: scripted demonstrations of a task from random resets (the
//! task's placement ranges and table offset, drawn from `--seed`), planned on privileged
//! state, written in the DexJoCo raw layout; plans that do not succeed are counted and
//! not written.

use anyhow::Context;
use dexjoco_formats::raw::RawFolder;
use dexjoco_formats::{EpisodeContainer, EpisodeMeta};
use dexjoco_sim::scripted::{self, Variant};
use dexjoco_sim::{TaskEnv, load_task_scene};
use rand::{Rng, SeedableRng};

use crate::cli::{GlobalArgs, ScriptedArgs};
use crate::exit::ExitStatus;
use crate::settings::ScriptedSettings;

/// Runs `scripted`.
pub fn run(global: &GlobalArgs, args: &ScriptedArgs) -> anyhow::Result<ExitStatus> {
    let ScriptedSettings {
        task: spec,
        episodes,
        scene,
        task_dir,
    } = ScriptedSettings::resolve(args)?;
    let scene = load_task_scene(&scene, spec)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(global.seed);
    let pb = crate::progress::bar(episodes as u64, "scripted", global.quiet);
    let mut written = 0usize;
    for k in 0..episodes {
        let s0 = TaskEnv::sample_initial_state(&scene, spec, &mut || rng.random::<f64>())?;
        let id = format!("{}_scripted_seed{}_{k}", spec.id, global.seed);
        let plan = scripted::plan(&scene, spec, &s0, &id, Variant::Demo)?;
        let line = match plan.success_at {
            Some(step) => {
                let dir = task_dir.join(format!("episode_{written:06}"));
                if dir.exists() {
                    fs_err::remove_dir_all(&dir)?;
                }
                RawFolder
                    .write(&dir, &plan.episode, spec, &EpisodeMeta::default())
                    .with_context(|| format!("writing '{}'", dir.display()))?;
                written += 1;
                format!("reset {k}: success at step {step} -> {}", dir.display())
            }
            None => format!(
                "reset {k}: no success in {} steps{} (not written)",
                plan.episode.len(),
                if plan.failed { ", task failed" } else { "" }
            ),
        };
        if !global.quiet {
            pb.suspend(|| errln!("{line}"));
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
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
