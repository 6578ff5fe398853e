//! Plans scripted click_mouse demonstrations on the reference scene for several random
//! initial states and replays each: `cargo run -p dexjoco-sim --example
//! click_mouse_demos -- [SEEDS] [SCENE_DIR]`.

use dexjoco_core::{Episode, TaskSpec};
use dexjoco_sim::{EnvOptions, TaskEnv, load_task_scene, scripted};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut args = std::env::args().skip(1);
    let seeds: u64 = args.next().map_or(Ok(4), |s| s.parse())?;
    let dir = args
        .next()
        .map_or_else(|| root.join("../shared/dexjoco-upstream/xmls"), Into::into);
    let spec = TaskSpec::from_file(&root.join("schemas/tasks/click_mouse.toml"))?;
    let scene = load_task_scene(&dir, &spec)?;
    let mut ok = 0;
    for seed in 0..seeds {
        // xorshift64* draws in [0, 1).
        let mut x = (seed + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut uniform = move || {
            x ^= x >> 12;
            x ^= x << 25;
            x ^= x >> 27;
            (x.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
        };
        let s0 = TaskEnv::sample_initial_state(&scene, &spec, &mut uniform)?;
        let ep = scripted::click_mouse_demo(&scene, &spec, &s0, &format!("click_mouse_{seed}"))?;
        let actions = ep.array(Episode::ACTION).expect("actions");
        let mut env = TaskEnv::from_initial_state(&scene, &spec, &s0, EnvOptions::default())?;
        let r = env.rollout(actions)?;
        ok += usize::from(r.succeeded());
        println!(
            "seed {seed}: mouse at ({:.3}, {:.3}), dh {:.3}: {} steps, replay success at {:?}",
            s0[23],
            s0[24],
            s0[30],
            ep.len(),
            r.first_success()
        );
    }
    println!("{ok}/{seeds} replays succeeded");
    Ok(())
}
