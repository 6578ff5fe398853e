//! `dexjoco-data bench augment`: the reference approach (re-simulate and render every
//! replay, one after another, in one process), ours with one and with N worker processes,
//! and the render-only limit of N processes (the same views of the episode's simulated
//! states drawn with no stepping and no encoding, the processes started together), on the
//! same episodes, seed and settings.

use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::Instant;

use anyhow::Context;
use dexjoco_augment::{
    AugmentConfig, AugmentReport, Executor, WorkerProcesses, augment_with, render_only,
};
use dexjoco_sim::SceneSource;
use serde::Serialize;

use crate::cli::{BenchAugmentArgs, BenchRenderLimitArgs, GlobalArgs, QualityArg};
use crate::exit::ExitStatus;
use crate::settings::render_settings;

/// One timed run.
#[derive(Debug, Serialize)]
struct Run {
    size: u32,
    quality: &'static str,
    approach: String,
    workers: usize,
    frames: usize,
    seconds: f64,
    frames_per_s: f64,
    /// This run's frames/s over the reference approach's.
    vs_reference: Option<f64>,
    /// This run's frames/s over ours with one worker.
    vs_one_worker: Option<f64>,
    /// This run's frames/s over the render-only limit of as many processes.
    of_limit: Option<f64>,
}

fn config(
    args: &BenchAugmentArgs,
    inputs: &[PathBuf],
    out: PathBuf,
    size: u32,
    q: QualityArg,
    seed: u64,
) -> AugmentConfig {
    AugmentConfig {
        inputs: inputs.to_vec(),
        out,
        replays: args.replays,
        tasks_dir: None,
        seed,
        scene: SceneSource::from_option(args.scene_dir.clone()),
        camera_pool: None,
        cameras: Vec::new(),
        settings: render_settings(size, q),
        keep_failed: true,
        max_frames: (args.max_frames > 0).then_some(args.max_frames),
        resimulate_per_replay: false,
        contact_sheet: false,
        depth: false,
        dynamics: false,
        extend_steps: 0,
        shard: None,
        overwrite: true,
    }
}

/// A run's row: rendered frames (every replay's steps) per second.
fn measured(
    size: u32,
    quality: QualityArg,
    approach: &str,
    workers: usize,
    report: &AugmentReport,
    seconds: f64,
) -> Run {
    let frames: usize = report.replays.iter().map(|r| r.steps).sum();
    Run {
        size,
        quality: quality.name(),
        approach: approach.to_owned(),
        workers,
        frames,
        seconds,
        frames_per_s: frames as f64 / seconds,
        vs_reference: None,
        vs_one_worker: None,
        of_limit: None,
    }
}

fn timed(config: &AugmentConfig, executor: &Executor) -> anyhow::Result<(AugmentReport, f64)> {
    let _ = fs_err::remove_dir_all(&config.out);
    let t = Instant::now();
    let report = augment_with(config, executor, &dexjoco_core::NoProgress)
        .with_context(|| format!("augmenting into {}", config.out.display()))?;
    let seconds = t.elapsed().as_secs_f64();
    let _ = fs_err::remove_dir_all(&config.out);
    Ok((report, seconds))
}

/// The render-only limit: `n` processes started together (a barrier after loading and
/// warm-up), their frames/s summed.
fn render_limit_of(
    args: &BenchAugmentArgs,
    input: &std::path::Path,
    size: u32,
    quality: QualityArg,
    n: usize,
) -> anyhow::Result<f64> {
    let exe = std::env::current_exe()?;
    let mut children = Vec::new();
    for _ in 0..n {
        let mut c = Command::new(&exe);
        c.args(["-q", "bench", "render-limit"])
            .arg(input)
            .args(["--size", &size.to_string(), "--quality", quality.name()])
            .args(["--frames", &args.limit_frames.to_string()])
            .args(["--replays", &args.replays.to_string()])
            .args(["--max-frames", &args.max_frames.to_string()]);
        // The same share of llvmpipe's raster threads as augment's worker processes get.
        dexjoco_augment::share_llvmpipe_threads(&mut c, n);
        if let Some(d) = &args.scene_dir {
            c.arg("--scene-dir").arg(d);
        }
        children.push(
            c.stdin(Stdio::piped())
                .stdout(Stdio::piped())
                .spawn()
                .context("starting a render-limit process")?,
        );
    }
    let mut readers: Vec<_> = children
        .iter_mut()
        .map(|c| BufReader::new(c.stdout.take().expect("piped")))
        .collect();
    for r in &mut readers {
        let mut line = String::new();
        r.read_line(&mut line)?;
        anyhow::ensure!(line.trim() == "ready", "render-limit process: {line}");
    }
    for c in &mut children {
        writeln!(c.stdin.as_mut().expect("piped"), "go")?;
    }
    let mut total = 0.0;
    for (mut c, mut r) in children.into_iter().zip(readers) {
        let mut line = String::new();
        r.read_line(&mut line)?;
        total += line
            .trim()
            .parse::<f64>()
            .with_context(|| format!("render-limit process said '{line}'"))?;
        c.wait()?;
    }
    Ok(total)
}

/// Runs `bench render-limit` (one process of the limit): loads, warms up, says `ready`,
/// waits for `go` on stdin, renders, prints frames/s.
pub fn render_limit(
    global: &GlobalArgs,
    args: &BenchRenderLimitArgs,
) -> anyhow::Result<ExitStatus> {
    let bench = BenchAugmentArgs {
        inputs: vec![args.input.clone()],
        scene_dir: args.scene_dir.clone(),
        replays: args.replays,
        max_frames: args.max_frames,
        sizes: vec![args.size],
        qualities: vec![args.quality],
        no_reference: true,
        limit_frames: args.frames,
    };
    let c = config(
        &bench,
        &bench.inputs,
        PathBuf::new(),
        args.size,
        args.quality,
        global.seed,
    );
    let fps = render_only(&c, args.frames, &mut || {
        println!("ready");
        let _ = std::io::stdout().flush();
        let mut go = String::new();
        let _ = std::io::stdin().read_line(&mut go);
    })?;
    println!("{fps}");
    Ok(ExitStatus::Success)
}

/// Runs `bench augment`.
pub fn run(global: &GlobalArgs, args: &BenchAugmentArgs) -> anyhow::Result<ExitStatus> {
    let inputs = if args.inputs.is_empty() {
        vec![super::augment::sample_data()?]
    } else {
        args.inputs.clone()
    };
    let first_input = dexjoco_formats::discover(&inputs, None)?
        .into_iter()
        .next()
        .context("no episode in the inputs")?
        .path;
    let workers = global.jobs.unwrap_or_else(|| {
        std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get)
    });
    let processes = |count| {
        Ok::<_, anyhow::Error>(Executor::Processes(WorkerProcesses {
            program: std::env::current_exe()?,
            args: vec!["-q".into(), "augment-worker".into()],
            count,
            egl_devices: Vec::new(),
        }))
    };
    let one_thread = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let tmp = tempfile::tempdir()?;
    let per_config = 3 + usize::from(!args.no_reference) + usize::from(args.limit_frames > 0);
    let bar = crate::progress::bar(
        (args.sizes.len() * args.qualities.len() * per_config) as u64,
        "bench augment",
        global.quiet,
    );
    let mut runs: Vec<Run> = Vec::new();
    let mut device = String::new();
    for &size in &args.sizes {
        for &quality in &args.qualities {
            let cfg = config(
                args,
                &inputs,
                tmp.path().join("out"),
                size,
                quality,
                global.seed,
            );
            let start = runs.len();
            let mut reference = None;
            if !args.no_reference {
                bar.set_message(format!("{size}px {} reference", quality.name()));
                let mut c = cfg.clone();
                c.resimulate_per_replay = true;
                let (report, s) = one_thread.install(|| timed(&c, &Executor::Threads))?;
                runs.push(measured(
                    size,
                    quality,
                    "reference (re-simulate every replay, 1 process)",
                    1,
                    &report,
                    s,
                ));
                bar.inc(1);
                reference = Some(runs.len() - 1);
            }
            bar.set_message(format!("{size}px {} ours x1", quality.name()));
            let (report, s) = timed(&cfg, &processes(1)?)?;
            runs.push(measured(
                size,
                quality,
                "ours, worker processes",
                1,
                &report,
                s,
            ));
            bar.inc(1);
            let one = runs.len() - 1;
            bar.set_message(format!("{size}px {} ours x{workers}", quality.name()));
            let (report, s) = timed(&cfg, &processes(workers)?)?;
            runs.push(measured(
                size,
                quality,
                "ours, worker processes",
                workers,
                &report,
                s,
            ));
            bar.inc(1);
            let limit = if args.limit_frames > 0 {
                bar.set_message(format!(
                    "{size}px {} render-only x{workers}",
                    quality.name()
                ));
                let l1 = render_limit_of(args, &first_input, size, quality, 1)?;
                let ln = render_limit_of(args, &first_input, size, quality, workers)?;
                bar.inc(1);
                Some((l1, ln))
            } else {
                None
            };
            let reference_fps = reference.map(|i| runs[i].frames_per_s);
            let one_fps = runs[one].frames_per_s;
            for r in &mut runs[start..] {
                r.vs_reference = reference_fps.map(|f| r.frames_per_s / f);
                r.vs_one_worker = Some(r.frames_per_s / one_fps);
                if let Some((l1, ln)) = limit {
                    r.of_limit = Some(r.frames_per_s / if r.workers == 1 { l1 } else { ln });
                }
            }
            if let Some((l1, ln)) = limit {
                for (n, l) in [(1, l1), (workers, ln)] {
                    runs.push(Run {
                        size,
                        quality: quality.name(),
                        approach: "render-only limit (trajectory states, no stepping, no encoding)"
                            .into(),
                        workers: n,
                        frames: 0,
                        seconds: 0.0,
                        frames_per_s: l,
                        vs_reference: reference_fps.map(|f| l / f),
                        vs_one_worker: Some(l / one_fps),
                        of_limit: None,
                    });
                }
            }
            if device.is_empty() {
                device = dexjoco_sim::Renderer::new(
                    &dexjoco_sim::Scene::from_xml_str(super::TABLETOP_XML, "probe")?.model,
                    cfg.settings,
                )
                .map(|r| r.device().label())
                .unwrap_or_default();
            }
        }
    }
    bar.finish_and_clear();

    let cores = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    outln!(
        "Augment of {} x {} replays{}, third-person view, H.264 encode included; {cores} core(s); device: {device}",
        inputs
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        args.replays,
        if args.max_frames > 0 {
            format!(" x {} frames", args.max_frames)
        } else {
            String::new()
        }
    );
    outln!();
    outln!(
        "| size | quality | approach | processes | frames/s | seconds | vs reference | vs 1 worker | of render-only limit |"
    );
    outln!("|---:|---|---|---:|---:|---:|---:|---:|---:|");
    let ratio = |x: Option<f64>, pct: bool| match (x, pct) {
        (Some(v), true) => format!("{:.0} %", v * 100.0),
        (Some(v), false) => format!("{v:.2}x"),
        (None, _) => "-".into(),
    };
    for r in &runs {
        outln!(
            "| {0}x{0} | {1} | {2} | {3} | {4:.1} | {5} | {6} | {7} | {8} |",
            r.size,
            r.quality,
            r.approach,
            r.workers,
            r.frames_per_s,
            if r.seconds > 0.0 {
                format!("{:.1}", r.seconds)
            } else {
                "-".into()
            },
            ratio(r.vs_reference, false),
            ratio(r.vs_one_worker, false),
            ratio(r.of_limit, true)
        );
    }
    let out = global.work_dir.join("bench");
    fs_err::create_dir_all(&out)?;
    let json = out.join("augment.json");
    dexjoco_formats::write_atomic(
        &json,
        serde_json::to_string_pretty(&serde_json::json!({
            "device": device,
            "cores": cores,
            "replays_per_episode": args.replays,
            "max_frames": args.max_frames,
            "runs": runs,
        }))?
        .as_bytes(),
    )?;
    errln!("wrote {}", json.display());
    Ok(ExitStatus::Success)
}
