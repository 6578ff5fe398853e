//! Plans scripted demonstrations on the reference scene for several random initial
//! states and replays each:
//! `cargo run -p dexjoco-sim --example scripted_demos -- TASK [SEEDS] [SCENE_DIR]`
//! with TASK `click_mouse` or `bimanual_unlock_ipad`.

use dexjoco_core::{Episode, TaskSpec};
use dexjoco_sim::{EnvOptions, TaskEnv, load_task_scene, scripted};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut args = std::env::args().skip(1);
    let task = args.next().unwrap_or_else(|| "click_mouse".into());
    let seeds: u64 = args.next().map_or(Ok(4), |s| s.parse())?;
    let dir = args
        .next()
        .map_or_else(|| root.join("../shared/dexjoco-upstream/xmls"), Into::into);
    let spec = TaskSpec::from_file(&root.join(format!("schemas/tasks/{task}.toml")))?;
    let scene = load_task_scene(&dexjoco_sim::SceneSource::Dir(dir), &spec)?;
    let mut ok = 0;
    for seed in 0..seeds {
        // xorshift64* draws in [0, 1), warmed up.
        let mut x = (seed + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut uniform = move || {
            x ^= x >> 12;
            x ^= x << 25;
            x ^= x >> 27;
            (x.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
        };
        for _ in 0..8 {
            uniform();
        }
        let s0 = TaskEnv::sample_initial_state(&scene, &spec, &mut uniform)?;
        let id = format!("{task}_{seed}");
        let ep = match task.as_str() {
            "click_mouse" => scripted::click_mouse_demo(&scene, &spec, &s0, &id)?,
            "bimanual_unlock_ipad" => scripted::unlock_ipad_demo(&scene, &spec, &s0, &id)?,
            other => return Err(format!("no scripted planner for '{other}'").into()),
        };
        let actions = ep.array(Episode::ACTION).expect("actions");
        let mut env = TaskEnv::from_initial_state(&scene, &spec, &s0, EnvOptions::default())?;
        let r = env.rollout(actions)?;
        ok += usize::from(r.succeeded());
        let p = spec.setup.proprio_dim();
        println!(
            "seed {seed}: first object at ({:.3}, {:.3}), dh {:.3}: {} steps, replay success at {:?}",
            s0[p],
            s0[p + 1],
            s0[s0.len() - 1],
            ep.len(),
            r.first_success()
        );
    }
    println!("{task}: {ok}/{seeds} replays succeeded");
    Ok(())
}
