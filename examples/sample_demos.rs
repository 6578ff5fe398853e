//! Makes the sample demonstrations shipped in `datasets/demos/`: scripted `click_mouse`
//! and `bimanual_unlock_ipad` episodes planned on the project's built-in scenes (so the
//! sample data needs nothing outside the repository), checked by replaying them, and
//! written in the DexJoCo raw layout (arrays only, no videos).
//!
//! `cargo run --release --example sample_demos -- [OUT] [PER_TASK]`
//! (defaults: `datasets/demos`, 2 per task).

use dexjoco_core::{Episode, TaskSpec};
use dexjoco_sim::{EnvOptions, TaskEnv, load_task_scene, scripted};
use rand::{Rng, SeedableRng};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let mut args = std::env::args().skip(1);
    let out = args
        .next()
        .map_or_else(|| root.join("datasets/demos"), Into::into);
    let per_task: usize = args.next().map_or(Ok(2), |s| s.parse())?;
    for task in ["click_mouse", "bimanual_unlock_ipad"] {
        let spec = TaskSpec::from_file(&root.join(format!("schemas/tasks/{task}.toml")))?;
        let scene = load_task_scene(&dexjoco_sim::SceneSource::BuiltIn, &spec)?;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2026);
        let mut written = 0;
        let mut attempt = 0;
        while written < per_task && attempt < 4 * per_task {
            attempt += 1;
            let s0 = TaskEnv::sample_initial_state(&scene, &spec, &mut || rng.random::<f64>())?;
            let id = format!("{task}_scripted_{attempt}");
            let ep = match task {
                "click_mouse" => scripted::click_mouse_demo(&scene, &spec, &s0, &id)?,
                _ => scripted::unlock_ipad_demo(&scene, &spec, &s0, &id)?,
            };
            // Keep only demonstrations whose replay succeeds.
            let mut env = TaskEnv::from_initial_state(&scene, &spec, &s0, EnvOptions::default())?;
            let replay = env.rollout(ep.array(Episode::ACTION).expect("actions"))?;
            if !replay.succeeded() {
                println!("{id}: replay did not succeed, not kept");
                continue;
            }
            let dir = out.join(task).join(format!("episode_{written:06}"));
            dexjoco_formats::raw::write_replay_zarr(&dir, &ep)?;
            println!(
                "{}: {} steps, success at step {:?}",
                dir.display(),
                ep.len(),
                replay.first_success()
            );
            written += 1;
        }
    }
    Ok(())
}
