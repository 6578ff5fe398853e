//! Plans scripted demonstrations for several random initial states and reports the
//! planner's success rate (no files written; `dexjoco-data scripted` writes them):
//! `cargo run -p dexjoco-sim --example scripted_demos -- TASK [SEEDS] [SCENE_DIR]`
//! (built-in scenes without SCENE_DIR or with `-`; a 4th argument `wrong` plans the
//! deliberately wrong variant).

use dexjoco_core::TaskSpec;
use dexjoco_scripted::{self as scripted, Variant};
use dexjoco_sim::{SceneSource, TaskEnv, load_task_scene};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let task = args.next().unwrap_or_else(|| "click_mouse".into());
    let seeds: u64 = args.next().map_or(Ok(4), |s| s.parse())?;
    let source = SceneSource::from_option(args.next().filter(|a| a != "-").map(Into::into));
    let wrong = args.next().is_some_and(|a| a == "wrong");
    let spec = TaskSpec::builtin(&task).ok_or("unknown task")?;
    let scene = load_task_scene(&source, spec)?;
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
        let s0 = TaskEnv::sample_initial_state(&scene, spec, &mut uniform)?;
        let t = std::time::Instant::now();
        let variant = if wrong { Variant::Wrong } else { Variant::Demo };
        let p = scripted::plan(&scene, spec, &s0, &format!("{task}_{seed}"), variant)?;
        ok += usize::from(p.success_at.is_some());
        println!(
            "seed {seed}: {} steps, success at {:?}, failed {} ({:.1} s)",
            p.episode.len(),
            p.success_at,
            p.failed,
            t.elapsed().as_secs_f64()
        );
        let ends: Vec<String> = p
            .subtasks
            .iter()
            .map(|e| format!("{} {}", e.id, e.end.map_or("-".into(), |s| s.to_string())))
            .collect();
        println!("  subtasks: {}", ends.join(", "));
        let phases: Vec<String> = p.phases.iter().map(|(id, s)| format!("{id} {s}")).collect();
        println!("  phases:   {}", phases.join(", "));
    }
    println!("{task}: {ok}/{seeds} plans succeeded");
    Ok(())
}
