//! Where the scripted planners think each subtask ends, against where the task spec's
//! predicates say it ends, over the resets `dexjoco-data scripted --seed S --episodes N`
//! draws: prints a Markdown table per scene set (docs/tasks-and-scenes.md holds its
//! output).
//!
//! `cargo run --release -p dexjoco-sim --example subtask_agreement -- [SEED] [N] [SCENE_DIR|-] [TASK...]`

use dexjoco_core::TaskSpec;
use dexjoco_scripted::{self as scripted, PLANNED_TASKS, Variant};
use dexjoco_sim::{SceneSource, TaskEnv, load_task_scene};
use rand::{Rng, SeedableRng};

/// One subtask's numbers over the successful plans.
#[derive(Default)]
struct Row {
    completed: usize,
    in_order: usize,
    diffs: Vec<i64>,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let seed: u64 = args.next().map_or(Ok(0), |s| s.parse())?;
    let n: usize = args.next().map_or(Ok(20), |s| s.parse())?;
    let dir = args.next().filter(|a| a != "-");
    let tasks: Vec<String> = {
        let t: Vec<String> = args.collect();
        if t.is_empty() {
            PLANNED_TASKS.iter().map(|s| (*s).to_owned()).collect()
        } else {
            t
        }
    };
    let source = SceneSource::from_option(dir.clone().map(Into::into));
    println!(
        "Scenes: {}; resets of `scripted --seed {seed} --episodes {n}`.\n",
        dir.as_deref().unwrap_or("built-in")
    );
    println!(
        "| task | subtask | plans that succeeded | ended, in order | planner phase end - predicate end (steps): median, min..max |"
    );
    println!("|---|---|---:|---:|---|");
    for task in &tasks {
        let spec = TaskSpec::builtin(task).ok_or("unknown task")?;
        let scene = load_task_scene(&source, spec)?;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut rows: Vec<Row> = spec.subtasks.iter().map(|_| Row::default()).collect();
        let mut succeeded = 0;
        for k in 0..n {
            let s0 = TaskEnv::sample_initial_state(&scene, spec, &mut || rng.random::<f64>())?;
            let p = scripted::plan(&scene, spec, &s0, &format!("{task}_{k}"), Variant::Demo)?;
            if p.success_at.is_none() {
                continue;
            }
            succeeded += 1;
            for (i, (row, span)) in rows.iter_mut().zip(&p.subtasks).enumerate() {
                let Some(end) = span.end else { continue };
                row.completed += 1;
                let before = &spec.subtask_predecessors()[i];
                let ordered = before
                    .iter()
                    .all(|&b| p.subtasks[b].end.is_some_and(|e| e <= end));
                row.in_order += usize::from(ordered);
                if let Some((_, phase)) = p.phases.iter().find(|(id, _)| id == &span.id) {
                    row.diffs.push(*phase as i64 - end as i64);
                }
            }
        }
        for (s, row) in spec.subtasks.iter().zip(&mut rows) {
            row.diffs.sort_unstable();
            let range = match (row.diffs.first(), row.diffs.last()) {
                (Some(a), Some(b)) => {
                    format!("{:+}, {a:+}..{b:+}", row.diffs[row.diffs.len() / 2])
                }
                _ => "-".into(),
            };
            println!(
                "| {task} | {} | {succeeded}/{n} | {}/{succeeded} | {range} |",
                s.text, row.in_order
            );
        }
    }
    Ok(())
}
