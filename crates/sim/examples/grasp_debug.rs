//! Debug: prints a task's grasp nodes along a scripted plan.
use dexjoco_core::{Episode, TaskSpec};
use dexjoco_sim::scripted::{self, Variant};
use dexjoco_sim::{EnvOptions, SceneSource, TaskEnv, load_task_scene};
fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let task = args.next().unwrap();
    let source = SceneSource::from_option(args.next().filter(|a| a != "-").map(Into::into));
    let nodes: Vec<String> = args.collect();
    let spec = TaskSpec::builtin(&task).ok_or("unknown task")?;
    let scene = load_task_scene(&source, spec)?;
    let mut x = 1u64.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
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
    let p = scripted::plan(&scene, spec, &s0, "x", Variant::Demo)?;
    let actions = p.episode.array(Episode::ACTION).unwrap();
    let mut env = TaskEnv::from_initial_state(&scene, spec, &s0, EnvOptions::default())?;
    for (t, a) in actions.rows().enumerate() {
        env.step(a)?;
        if t % 20 == 0 {
            let vals: Vec<String> = nodes
                .iter()
                .map(|n| {
                    let (b, o) = n
                        .split_once('.')
                        .map_or((n.as_str(), None), |(b, o)| (b, Some(o)));
                    match o {
                        Some(o) => format!("{n}={:?}", env.checker().output(b, o)),
                        None => format!("{n}={:?}", env.checker().value(b)),
                    }
                })
                .collect();
            println!("{t}: {}", vals.join(" "));
        }
    }
    Ok(())
}
