//! Generation success per task, writing no episodes: sources are the shipped sample
//! demonstration of each task (`datasets/demos`) plus `SCRIPTED` scripted plans (from
//! `scripted --seed 1000`'s resets), attempts from `generate --seed SEED`'s resets; prints
//! a Markdown table (attempts, successes, where the failures stopped, time per attempt).
//! `GEN_DEBUG=1` prints each failure; `GEN_FIGURES=DIR` writes each task's pose-spread
//! figure (`DIR/<task>.png`, as `generate_poses.png`) and all of them in `DIR/all.png`.
//!
//! `cargo run --release -p dexjoco-generate --example generate_rates -- [ATTEMPTS] [SCRIPTED] [SCENE_DIR|-] [TASK...]`

use std::collections::BTreeMap;
use std::time::Instant;

use dexjoco_core::TaskSpec;
use dexjoco_generate::{AttemptOptions, AttemptRecord, SourceDemo, attempt, write_pose_figure};
use dexjoco_scripted::{self as scripted, PLANNED_TASKS, Variant};
use dexjoco_sim::{SceneSource, TaskEnv, load_task_scene};
use rand::{Rng, SeedableRng};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let attempts: usize = args.next().map_or(Ok(20), |s| s.parse())?;
    let scripted_sources: usize = args.next().map_or(Ok(0), |s| s.parse())?;
    let dir = args.next().filter(|a| a != "-");
    let tasks: Vec<String> = {
        let t: Vec<String> = args.collect();
        if t.is_empty() {
            PLANNED_TASKS.iter().map(|s| (*s).to_owned()).collect()
        } else {
            t
        }
    };
    let source = dir.map_or(SceneSource::BuiltIn, |d| SceneSource::Dir(d.into()));
    let demos = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../datasets/demos");
    println!("| task | sources | attempts | successes | rate | failed at | s / attempt |");
    println!("|---|---:|---:|---:|---:|---|---:|");
    for task in &tasks {
        let spec = TaskSpec::builtin(task).ok_or("unknown task")?;
        let scene = load_task_scene(&source, spec)?;
        let mut sources = Vec::new();
        let raw =
            dexjoco_formats::raw::read_raw_episode(&demos.join(task).join("episode_000000"), spec)?;
        let mut ep = raw.episode;
        ep.id = format!("{task}_sample");
        match SourceDemo::prepare(&scene, spec, &ep, 0) {
            Ok(s) => sources.push(s),
            Err(e) => eprintln!("{task}: sample not usable: {e}"),
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1000);
        for k in 0..scripted_sources {
            let s0 = TaskEnv::sample_initial_state(&scene, spec, &mut || rng.random::<f64>())?;
            let p = scripted::plan(
                &scene,
                spec,
                &s0,
                &format!("{task}_scripted_{k}"),
                Variant::Demo,
            )?;
            if p.success_at.is_some()
                && let Ok(s) = SourceDemo::prepare(&scene, spec, &p.episode, 0)
            {
                sources.push(s);
            }
        }
        if sources.is_empty() {
            println!("| {task} | 0 | - | - | - | no usable source | - |");
            continue;
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let mut ok = 0;
        let mut failed: BTreeMap<String, usize> = BTreeMap::new();
        let t = Instant::now();
        let mut records = Vec::new();
        for k in 0..attempts {
            let s0 = TaskEnv::sample_initial_state(&scene, spec, &mut || rng.random::<f64>())?;
            let a = attempt(&scene, spec, &sources, s0, k, 0, &AttemptOptions::default())?;
            records.push(AttemptRecord::of(&a, 0));
            match &a.failure {
                None => ok += 1,
                Some(f) => {
                    if std::env::var_os("GEN_DEBUG").is_some() {
                        eprintln!("{task} attempt {k}: {f:?}");
                    }
                    *failed
                        .entry(f.subtask.clone().unwrap_or_else(|| "-".into()))
                        .or_default() += 1
                }
            }
        }
        let per = t.elapsed().as_secs_f64() / attempts.max(1) as f64;
        if let Some(dir) = std::env::var_os("GEN_FIGURES") {
            let resets: Vec<Vec<f64>> = sources.iter().map(|s| s.reset.clone()).collect();
            let refs: Vec<&AttemptRecord> = records.iter().collect();
            let path = std::path::Path::new(&dir).join(format!("{task}.png"));
            write_pose_figure(&path, spec, &resets, &refs)?;
        }
        let failed: Vec<String> = failed.iter().map(|(s, n)| format!("{s} {n}")).collect();
        println!(
            "| {task} | {} | {attempts} | {ok} | {:.0} % | {} | {per:.2} |",
            sources.len(),
            100.0 * ok as f64 / attempts.max(1) as f64,
            failed.join(", ")
        );
    }
    if let Some(dir) = std::env::var_os("GEN_FIGURES") {
        montage(std::path::Path::new(&dir), &tasks)?;
    }
    Ok(())
}

/// `DIR/all.png`: every task's figure, two to a row.
fn montage(dir: &std::path::Path, tasks: &[String]) -> Result<(), Box<dyn std::error::Error>> {
    let figures = tasks
        .iter()
        .filter_map(|t| image::open(dir.join(format!("{t}.png"))).ok())
        .map(|i| i.to_rgb8())
        .collect::<Vec<_>>();
    let cell_w = figures
        .iter()
        .map(image::RgbImage::width)
        .max()
        .unwrap_or(1);
    let cell_h = figures
        .iter()
        .map(image::RgbImage::height)
        .max()
        .unwrap_or(1);
    let rows = figures.len().div_ceil(2) as u32;
    let mut sheet = image::RgbImage::from_pixel(2 * cell_w, rows * cell_h, image::Rgb([255; 3]));
    for (i, f) in figures.iter().enumerate() {
        let (c, r) = (i as u32 % 2, i as u32 / 2);
        image::imageops::replace(&mut sheet, f, i64::from(c * cell_w), i64::from(r * cell_h));
    }
    sheet.save(dir.join("all.png"))?;
    Ok(())
}
