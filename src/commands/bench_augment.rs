//! `dexjoco-data bench augment`: the reference approach (re-simulate and render every
//! replay, one after another, in one process), ours with one and with N worker processes,
//! and the render-only limit of N processes (the same views of the episode's simulated
//! states drawn with no stepping and no encoding, the processes started together), on the
//! same episodes, seed and settings.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use anyhow::Context;
use dexjoco_augment::{
    AugmentConfig, AugmentRun, Executor, GeometryDifference, StageTimes, WorkerProcesses,
    augment_with, geometry_difference, render_only,
};
use dexjoco_render::RenderSettings;
use dexjoco_sim::SceneSource;
use serde::Serialize;

use crate::cli::{BenchRenderLimitArgs, GeometryArg, GlobalArgs, QualityArg};
use crate::exit::ExitStatus;
use crate::settings::{BenchAugmentSettings, render_settings};

/// One timed run.
#[derive(Debug, Serialize)]
struct Run {
    size: u32,
    quality: &'static str,
    geometry: &'static str,
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
    /// Where its time went (augment runs).
    times: Option<StageTimes>,
}

fn config(
    args: &BenchAugmentSettings,
    inputs: &[PathBuf],
    out: PathBuf,
    look: Look,
    seed: u64,
) -> AugmentConfig {
    let Look(size, q, geometry) = look;
    AugmentConfig {
        inputs: inputs.to_vec(),
        out,
        replays: args.replays,
        tasks_dir: None,
        seed,
        scene: SceneSource::from_option(args.scene_dir.clone()),
        camera_pool: None,
        cameras: Vec::new(),
        settings: RenderSettings {
            geometry: geometry.geometry(),
            ..render_settings(size, q)
        },
        keep_failed: true,
        max_frames: (args.max_frames > 0).then_some(args.max_frames),
        resimulate_per_replay: false,
        contact_sheet: false,
        depth: false,
        dynamics: false,
        extend_steps: 0,
        shard: None,
        overwrite: true,
        video: dexjoco_augment::VideoEncoding::default(),
        renderer: args.renderer,
        warp: args.warp.clone(),
    }
}

/// What a configuration renders: size, preset and geometry.
#[derive(Debug, Clone, Copy)]
struct Look(u32, QualityArg, GeometryArg);

/// A run's row: rendered frames (every replay's steps) per second.
fn measured(
    Look(size, quality, geometry): Look,
    approach: &str,
    workers: usize,
    report: &AugmentRun,
    seconds: f64,
) -> Run {
    let frames: usize = report.replays.iter().map(|r| r.steps).sum();
    Run {
        size,
        quality: quality.name(),
        geometry: geometry.geometry().name(),
        approach: approach.to_owned(),
        workers,
        frames,
        seconds,
        frames_per_s: frames as f64 / seconds,
        vs_reference: None,
        vs_one_worker: None,
        of_limit: None,
        times: Some(report.times),
    }
}

fn timed(config: &AugmentConfig, executor: &Executor) -> anyhow::Result<(AugmentRun, f64)> {
    let _ = fs_err::remove_dir_all(&config.out);
    let t = Instant::now();
    let report = augment_with(config, executor, &dexjoco_core::NoProgress)
        .with_context(|| format!("augmenting into {}", config.out.display()))?;
    let seconds = t.elapsed().as_secs_f64();
    let _ = fs_err::remove_dir_all(&config.out);
    Ok((report, seconds))
}

/// The command line of one render-limit process: this run's look, episode, replays,
/// frames and seed (the views it draws are sampled from the seed).
fn render_limit_command(
    exe: &Path,
    args: &BenchAugmentSettings,
    input: &Path,
    Look(size, quality, geometry): Look,
) -> Command {
    let mut c = Command::new(exe);
    c.args([
        "-q",
        "--seed",
        &args.seed.to_string(),
        "bench",
        "render-limit",
    ])
    .arg(input)
    .args(["--size", &size.to_string(), "--quality", quality.name()])
    .args(["--geometry", geometry.geometry().name()])
    .args(["--frames", &args.limit_frames.to_string()])
    .args(["--replays", &args.replays.to_string()])
    .args(["--max-frames", &args.max_frames.to_string()]);
    if let Some(d) = &args.scene_dir {
        c.arg("--scene-dir").arg(d);
    }
    c
}

/// The render-only limit: `n` processes started together (a barrier after loading and
/// warm-up), their frames/s summed.
fn render_limit_of(
    args: &BenchAugmentSettings,
    input: &Path,
    look: Look,
    n: usize,
) -> anyhow::Result<f64> {
    let exe = std::env::current_exe()?;
    let mut children = Vec::new();
    for _ in 0..n {
        let mut c = render_limit_command(&exe, args, input, look);
        // The same share of llvmpipe's raster threads as augment's worker processes get.
        dexjoco_augment::share_llvmpipe_threads(&mut c, n);
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
    let bench = BenchAugmentSettings {
        inputs: vec![args.input.clone()],
        scene_dir: args.scene_dir.clone(),
        replays: args.replays,
        max_frames: args.max_frames,
        sizes: vec![args.size],
        qualities: vec![args.quality],
        no_reference: true,
        limit_frames: args.frames,
        workers: Vec::new(),
        threads: false,
        first_frame_timeout: dexjoco_augment::DEFAULT_FIRST_FRAME_TIMEOUT,
        geometry: vec![args.geometry],
        seed: global.seed,
        quiet: global.quiet,
        out: PathBuf::new(),
        renderer: dexjoco_render::RendererKind::Opengl,
        warp: dexjoco_render::warp::WarpOptions::default(),
    };
    let c = config(
        &bench,
        &bench.inputs,
        PathBuf::new(),
        Look(args.size, args.quality, args.geometry),
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

/// One configuration's runs: the reference approach, ours with each worker count, and the
/// render-only limits.
fn bench_config(
    ctx: &BenchContext<'_>,
    look: Look,
    bar: &indicatif::ProgressBar,
) -> anyhow::Result<Vec<Run>> {
    let args = ctx.args;
    let Look(size, quality, geometry) = look;
    let cfg = config(args, &ctx.inputs, ctx.out.clone(), look, ctx.seed);
    let label = |what: String| {
        format!(
            "{size}px {} {} {what}",
            quality.name(),
            geometry.geometry().name()
        )
    };
    let mut runs: Vec<Run> = Vec::new();
    if !args.no_reference {
        bar.set_message(label("reference".into()));
        let mut c = cfg.clone();
        c.resimulate_per_replay = true;
        let one_thread = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
        let (report, s) = one_thread.install(|| timed(&c, &Executor::Threads))?;
        runs.push(measured(look, REFERENCE, 1, &report, s));
        bar.inc(1);
    }
    for &n in &ctx.workers {
        bar.set_message(label(format!("ours x{n}")));
        let (report, s) = if args.threads {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(n).build()?;
            pool.install(|| timed(&cfg, &Executor::Threads))?
        } else {
            timed(&cfg, &processes(args, n)?)?
        };
        let approach = match (args.threads, args.renderer) {
            (true, _) => OURS_THREADS,
            (false, dexjoco_render::RendererKind::Warp) => OURS_WARP,
            (false, dexjoco_render::RendererKind::Opengl) => OURS,
        };
        runs.push(measured(look, approach, n, &report, s));
        bar.inc(1);
    }
    let mut limits = Vec::new();
    if args.limit_frames > 0 {
        for &n in &ctx.workers {
            bar.set_message(label(format!("render-only x{n}")));
            limits.push((n, render_limit_of(args, &ctx.first_input, look, n)?));
        }
        bar.inc(1);
    }
    let reference_fps = runs
        .iter()
        .find(|r| r.approach == REFERENCE)
        .map(|r| r.frames_per_s);
    let one_fps = runs
        .iter()
        .find(|r| r.approach != REFERENCE && r.approach != LIMIT && r.workers == 1)
        .map(|r| r.frames_per_s);
    for (n, l) in &limits {
        runs.push(Run {
            size,
            quality: quality.name(),
            geometry: geometry.geometry().name(),
            approach: LIMIT.into(),
            workers: *n,
            frames: 0,
            seconds: 0.0,
            frames_per_s: *l,
            vs_reference: None,
            vs_one_worker: None,
            of_limit: None,
            times: None,
        });
    }
    for r in &mut runs {
        r.vs_reference = reference_fps.map(|f| r.frames_per_s / f);
        r.vs_one_worker = one_fps.map(|f| r.frames_per_s / f);
        if r.approach != LIMIT {
            r.of_limit = limits
                .iter()
                .find(|(n, _)| *n == r.workers)
                .map(|(_, l)| r.frames_per_s / l);
        }
    }
    Ok(runs)
}

const REFERENCE: &str = "reference (re-simulate every replay, 1 process)";
const OURS: &str = "ours, worker processes";
const OURS_THREADS: &str = "ours, threads of one process";
const OURS_WARP: &str = "ours, worker processes, Warp renderer";
const LIMIT: &str = "render-only limit (trajectory states, no stepping, no encoding)";

/// `count` worker processes of this binary, dealt over the node's GPUs as `augment` does.
fn processes(args: &BenchAugmentSettings, count: usize) -> anyhow::Result<Executor> {
    Ok(Executor::Processes(
        WorkerProcesses::new(
            std::env::current_exe()?,
            vec!["-q".into(), "augment-worker".into()],
            count,
        )
        .with_egl_devices(crate::settings::render_workers(Some(count), Vec::new()).1)
        .with_first_frame_timeout(args.first_frame_timeout),
    ))
}

/// What every configuration shares.
struct BenchContext<'a> {
    args: &'a BenchAugmentSettings,
    inputs: Vec<PathBuf>,
    first_input: PathBuf,
    out: PathBuf,
    seed: u64,
    /// Worker counts of our runs.
    workers: Vec<usize>,
}

/// Runs `bench augment`.
pub fn run(args: &BenchAugmentSettings) -> anyhow::Result<ExitStatus> {
    let inputs = args.inputs.clone();
    let first_input = first_episode(&inputs)?;
    let cores = dexjoco_core::available_cores();
    let tmp = tempfile::tempdir()?;
    let ctx = BenchContext {
        args,
        inputs,
        first_input,
        out: tmp.path().join("out"),
        seed: args.seed,
        workers: args.workers.clone(),
    };
    let per_config =
        ctx.workers.len() + usize::from(!args.no_reference) + usize::from(args.limit_frames > 0);
    let looks: Vec<Look> = args
        .sizes
        .iter()
        .flat_map(|&s| args.qualities.iter().map(move |&q| (s, q)))
        .flat_map(|(s, q)| args.geometry.iter().map(move |&g| Look(s, q, g)))
        .collect();
    let bar = crate::progress::bar(
        (looks.len() * per_config) as u64,
        "bench augment",
        args.quiet,
    );
    let mut runs: Vec<Run> = Vec::new();
    for &look in &looks {
        runs.extend(bench_config(&ctx, look, &bar)?);
    }
    let differences = light_differences(&ctx, &looks, &bar)?;
    bar.finish_and_clear();
    let device = render_device(args)?;
    print_runs(&ctx, &runs, &device, cores);
    print_differences(&runs, &differences);
    write_results(args, &device, cores, &runs, &differences)?;
    Ok(ExitStatus::Success)
}

/// The first episode in the inputs.
fn first_episode(inputs: &[PathBuf]) -> anyhow::Result<PathBuf> {
    Ok(dexjoco_formats::discover(inputs, None)?
        .into_iter()
        .next()
        .context("no episode in the inputs")?
        .path)
}

/// With both geometries measured, the image difference of the light geometry to the
/// full one at each light look.
fn light_differences(
    ctx: &BenchContext<'_>,
    looks: &[Look],
    bar: &indicatif::ProgressBar,
) -> anyhow::Result<Vec<(Look, GeometryDifference)>> {
    let args = ctx.args;
    let mut differences = Vec::new();
    if args.geometry.contains(&GeometryArg::Full) && args.geometry.contains(&GeometryArg::Light) {
        for &look in looks.iter().filter(|l| l.2 == GeometryArg::Light) {
            bar.set_message(format!("{}px {} image difference", look.0, look.1.name()));
            let cfg = config(args, &ctx.inputs, ctx.out.clone(), look, ctx.seed);
            differences.push((look, geometry_difference(&cfg, DIFFERENCE_FRAMES)?));
        }
    }
    Ok(differences)
}

/// The rendering device at the first look's settings (empty when none opens); with the
/// Warp renderer, its worker's device too.
fn render_device(args: &BenchAugmentSettings) -> anyhow::Result<String> {
    let settings = render_settings(args.sizes[0], args.qualities[0]);
    let egl = dexjoco_render::Renderer::new(
        &dexjoco_sim::Scene::from_xml_str(super::TABLETOP_XML, "probe")?.model,
        settings,
    )
    .map(|r| r.device().label())
    .unwrap_or_default();
    if args.renderer != dexjoco_render::RendererKind::Warp {
        return Ok(egl);
    }
    let warp = dexjoco_render::warp::WarpWorker::start(&args.warp)
        .map_or_else(|e| format!("unavailable: {e}"), |w| w.info().describe());
    Ok(format!("{warp} (Warp rows); {egl} (OpenGL rows)"))
}

/// Writes the runs and image differences to `<work dir>/bench/augment.json`.
fn write_results(
    args: &BenchAugmentSettings,
    device: &str,
    cores: usize,
    runs: &[Run],
    differences: &[(Look, GeometryDifference)],
) -> anyhow::Result<()> {
    fs_err::create_dir_all(&args.out)?;
    let json = args.out.join("augment.json");
    dexjoco_formats::write_atomic(
        &json,
        serde_json::to_string_pretty(&serde_json::json!({
            "device": device,
            "cores": cores,
            "replays_per_episode": args.replays,
            "max_frames": args.max_frames,
            "runs": runs,
            "light_geometry": differences.iter().map(|(Look(size, q, _), d)| serde_json::json!({
                "size": size, "quality": q.name(), "difference": d,
            })).collect::<Vec<_>>(),
        }))?
        .as_bytes(),
    )?;
    errln!("wrote {}", json.display());
    Ok(())
}

/// The speed table and the per-stage table.
fn print_runs(ctx: &BenchContext<'_>, runs: &[Run], device: &str, cores: usize) {
    let args = ctx.args;
    outln!(
        "Augment of {} x {} replays{}, third-person view, H.264 encode included; {cores} core(s); device: {device}",
        ctx.inputs
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
        "| size | quality | geometry | approach | workers | frames/s | seconds | vs reference | vs 1 worker | of render-only limit |"
    );
    outln!("|---:|---|---|---|---:|---:|---:|---:|---:|---:|");
    let ratio = |x: Option<f64>, pct: bool| match (x, pct) {
        (Some(v), true) => format!("{:.0} %", v * 100.0),
        (Some(v), false) => format!("{v:.2}x"),
        (None, _) => "-".into(),
    };
    for r in runs {
        outln!(
            "| {0}x{0} | {1} | {9} | {2} | {3} | {4:.1} | {5} | {6} | {7} | {8} |",
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
            ratio(r.of_limit, true),
            r.geometry
        );
    }
    outln!();
    outln!(
        "Where a frame's time goes: milliseconds of work per rendered frame, summed over the processes (the x264 encoders run in processes of their own), and each stage's share"
    );
    outln!();
    // The render checks' column comes last, after the stages of making a frame.
    let names = StageTimes::default().stages().map(|(n, _)| n);
    let (making, checks) = names.split_at(names.len() - 1);
    outln!(
        "| size | quality | geometry | approach | workers | {} | bottleneck | {} |",
        making.join(" | "),
        checks.join(" | ")
    );
    outln!(
        "|---:|---|---|---|---:|{}---|{}",
        "---:|".repeat(making.len()),
        "---:|".repeat(checks.len())
    );
    for r in runs {
        let Some(t) = &r.times else { continue };
        let total = t.total().max(f64::MIN_POSITIVE);
        let cells: Vec<String> = t
            .stages()
            .iter()
            .map(|(_, s)| format!("{:.2} ({:.0} %)", t.ms_per_frame(*s), 100.0 * s / total))
            .collect();
        let (making, checks) = cells.split_at(cells.len() - 1);
        outln!(
            "| {0}x{0} | {1} | {6} | {2} | {3} | {4} | {5} | {7} |",
            r.size,
            r.quality,
            r.approach,
            r.workers,
            making.join(" | "),
            t.bottleneck(),
            r.geometry,
            checks.join(" | ")
        );
    }
    print_checks_share(runs);
    if args.renderer == dexjoco_render::RendererKind::Warp {
        let batch = args.warp.worlds.map_or_else(
            || "the default: 2048 images on a GPU, 16 on the CPU".to_owned(),
            |n| format!("{n} images"),
        );
        outln!();
        outln!(
            "Warp renderer ({} device, batch: {batch}): its stages read \
             scene update = the step's geom poses and each image's view, lights and table look \
             packed into batches, piped to the worker and copied to the device; \
             render = BVH refit and ray tracing on the device; \
             readback = images copied to the worker's memory, piped back and unpacked. \
             The reference and render-only rows use MuJoCo's OpenGL renderer.",
            args.warp.device
        );
    }
}

/// What the render checks cost: their share of each augment run's work, smallest and
/// largest.
fn print_checks_share(runs: &[Run]) {
    let shares: Vec<(f64, f64)> = runs
        .iter()
        .filter_map(|r| r.times.as_ref())
        .filter(|t| t.frames > 0)
        .map(|t| {
            let share = 100.0 * t.checks / t.total().max(f64::MIN_POSITIVE);
            (share, t.ms_per_frame(t.checks))
        })
        .collect();
    if shares.is_empty() {
        return;
    }
    let (lo, hi) = shares.iter().fold((f64::MAX, 0.0f64), |(lo, hi), (s, _)| {
        (lo.min(*s), hi.max(*s))
    });
    let ms = shares.iter().map(|(_, m)| *m).fold(0.0f64, f64::max);
    outln!();
    outln!(
        "Render checks (blank, frozen, non-finite; every frame): {lo:.2}-{hi:.2} % of the work, at most {ms:.3} ms per frame"
    );
}

/// Frames of a replay compared between the full and the light geometry.
const DIFFERENCE_FRAMES: usize = 60;

/// The light geometry's speed-up (per worker count) and image difference to the full one.
fn print_differences(runs: &[Run], differences: &[(Look, GeometryDifference)]) {
    if differences.is_empty() {
        return;
    }
    outln!();
    outln!(
        "Light geometry against full: triangles drawn, speed-up of our runs, and the image difference over {DIFFERENCE_FRAMES} frames of a replay (RGB as rendered, before encoding)"
    );
    outln!();
    outln!(
        "| size | quality | triangles full -> light | speed-up (workers: x) | PSNR mean (min) | SSIM mean (min) |"
    );
    outln!("|---:|---|---:|---|---:|---:|");
    for (Look(size, q, _), d) in differences {
        let ours = |geometry: &'static str| {
            runs.iter()
                .filter(move |r| {
                    r.size == *size
                        && r.quality == q.name()
                        && r.geometry == geometry
                        && (r.approach == OURS || r.approach == OURS_THREADS)
                })
                .map(|r| (r.workers, r.frames_per_s))
        };
        let speedups: Vec<String> = ours("light")
            .filter_map(|(n, light)| {
                ours("full")
                    .find(|(m, _)| *m == n)
                    .map(|(_, full)| format!("{n}: {:.2}x", light / full))
            })
            .collect();
        outln!(
            "| {size}x{size} | {} | {} -> {} | {} | {:.1} dB ({:.1}) | {:.4} ({:.4}) |",
            q.name(),
            d.triangles_full,
            d.triangles_light,
            speedups.join(", "),
            d.psnr_mean,
            d.psnr_min,
            d.ssim_mean,
            d.ssim_min
        );
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::cli::{BenchCommand, Cli, Command as Sub};

    #[test]
    fn render_limit_processes_get_the_global_seed() {
        let cli = Cli::parse_from(["dexjoco-data", "--seed", "7", "bench", "augment"]);
        let Sub::Bench(BenchCommand::Augment(args)) = cli.command else {
            panic!("parsed another command");
        };
        let args = BenchAugmentSettings::resolve(&args, &cli.global, || Ok("demos".into()))
            .expect("resolves");
        let look = Look(32, QualityArg::Fast, GeometryArg::Full);
        let c = render_limit_command(Path::new("exe"), &args, Path::new("ep"), look);
        let argv: Vec<_> = c
            .get_args()
            .map(|a| a.to_string_lossy().into_owned())
            .collect();
        let at = argv
            .iter()
            .position(|a| a == "--seed")
            .expect("--seed passed on");
        assert_eq!(argv[at + 1], "7", "{argv:?}");
        // Parsed back by the child as its global seed.
        let child = Cli::parse_from(std::iter::once("exe".to_owned()).chain(argv));
        assert_eq!(child.global.seed, 7);
    }
}
