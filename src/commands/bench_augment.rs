//! `dexjoco-data bench augment`: our augment (physics once per episode, rendered in
//! parallel) against the reference approach (re-simulate and render every replay, one
//! after another, in one process), on the same episodes, seed and settings.

use std::time::Instant;

use anyhow::Context;
use dexjoco_augment::{AugmentConfig, AugmentReport, augment};
use dexjoco_sim::{RenderQuality, RenderSettings, SceneSource};
use serde::Serialize;

use crate::cli::{BenchAugmentArgs, GlobalArgs};
use crate::exit::ExitStatus;

/// One timed run.
#[derive(Debug, Serialize)]
struct Run {
    size: u32,
    preset: &'static str,
    approach: String,
    threads: usize,
    replays: usize,
    frames: usize,
    seconds: f64,
    frames_per_s: f64,
    replays_per_min: f64,
    /// Reference seconds / these seconds.
    speedup: f64,
}

fn timed(config: &AugmentConfig, threads: usize) -> anyhow::Result<(AugmentReport, f64)> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .thread_name(|i| format!("bench-augment-{i}"))
        .build()
        .context("starting worker threads")?;
    let _ = fs_err::remove_dir_all(&config.out);
    let t = Instant::now();
    let report = pool
        .install(|| augment(config, &dexjoco_core::NoProgress))
        .with_context(|| format!("augmenting into {}", config.out.display()))?;
    let seconds = t.elapsed().as_secs_f64();
    let _ = fs_err::remove_dir_all(&config.out);
    Ok((report, seconds))
}

/// Runs `bench augment`.
pub fn run(global: &GlobalArgs, args: &BenchAugmentArgs) -> anyhow::Result<ExitStatus> {
    let inputs = if args.inputs.is_empty() {
        vec![super::augment::sample_data()?]
    } else {
        args.inputs.clone()
    };
    let jobs = global.jobs.unwrap_or_else(|| {
        std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
    });
    let tmp = tempfile::tempdir()?;
    let mut approaches: Vec<(&str, bool, usize)> = vec![("reference", true, 1)];
    if !args.no_single_thread {
        approaches.push(("ours", false, 1));
    }
    if jobs > 1 || args.no_single_thread {
        approaches.push(("ours", false, jobs));
    }
    let total = (args.sizes.len() * args.presets.len() * approaches.len()) as u64;
    let bar = crate::progress::bar(total, "bench augment", global.quiet);
    let mut runs: Vec<Run> = Vec::new();
    let mut device = String::new();
    for &size in &args.sizes {
        for &preset in &args.presets {
            let mut reference_s = None;
            for &(name, resimulate, threads) in &approaches {
                bar.set_message(format!("{size}px {} {name} x{threads}", preset.name()));
                let config = AugmentConfig {
                    inputs: inputs.clone(),
                    out: tmp.path().join("out"),
                    replays: args.replays,
                    tasks_dir: None,
                    seed: global.seed,
                    scene: SceneSource::BuiltIn,
                    camera_pool: None,
                    cameras: Vec::new(),
                    settings: RenderSettings {
                        width: size,
                        height: size,
                        quality: RenderQuality::from_name(preset.name()).expect("preset"),
                        depth: false,
                    },
                    keep_failed: true,
                    max_frames: Some(args.max_frames),
                    resimulate_per_replay: resimulate,
                    contact_sheet: false,
                    depth: false,
                    dynamics: false,
                };
                let (report, seconds) = timed(&config, threads)?;
                if device.is_empty() {
                    device = dexjoco_sim::Renderer::new(
                        &dexjoco_sim::Scene::from_xml_str(super::TABLETOP_XML, "probe")?.model,
                        config.settings,
                    )
                    .map(|r| r.device().label())
                    .unwrap_or_default();
                }
                let replays = report.replays.len();
                let frames: usize = report.replays.iter().map(|r| r.steps).sum();
                anyhow::ensure!(replays > 0, "no replay was written");
                let reference = *reference_s.get_or_insert(seconds);
                runs.push(Run {
                    size,
                    preset: preset.name(),
                    approach: name.to_owned(),
                    threads,
                    replays,
                    frames,
                    seconds,
                    frames_per_s: frames as f64 / seconds,
                    replays_per_min: replays as f64 * 60.0 / seconds,
                    speedup: reference / seconds,
                });
                bar.inc(1);
            }
        }
    }
    bar.finish_and_clear();

    let episodes = runs.first().map_or(0, |r| r.replays / args.replays.max(1));
    outln!(
        "Augment of {episodes} episode(s) x {} replays x {} frames (third-person view, H.264 \
         encode included); device: {device}",
        args.replays,
        args.max_frames
    );
    outln!();
    outln!(
        "| size | preset | approach | threads | rendered frames/s | replays/min | seconds | speed-up vs reference |"
    );
    outln!("|---:|---|---|---:|---:|---:|---:|---:|");
    for r in &runs {
        outln!(
            "| {0}x{0} | {1} | {2} | {3} | {4:.1} | {5:.1} | {6:.1} | {7:.2}x |",
            r.size,
            r.preset,
            r.approach,
            r.threads,
            r.frames_per_s,
            r.replays_per_min,
            r.seconds,
            r.speedup
        );
    }
    let out = global.work_dir.join("bench");
    fs_err::create_dir_all(&out)?;
    let json = out.join("augment.json");
    dexjoco_formats::write_atomic(
        &json,
        serde_json::to_string_pretty(&serde_json::json!({
            "device": device,
            "replays_per_episode": args.replays,
            "max_frames": args.max_frames,
            "runs": runs,
        }))?
        .as_bytes(),
    )?;
    errln!("wrote {}", json.display());
    Ok(ExitStatus::Success)
}
