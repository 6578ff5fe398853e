//! `dexjoco-data bench convert`: our `convert` against lerobot's own dataset writer on
//! the same generated episodes (wall time, peak memory of each child process), and our
//! peak memory for few vs many short episodes.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::Context;
use dexjoco_core::TaskSpec;
use serde::Serialize;

use crate::cli::{BenchConvertArgs, GlobalArgs};
use crate::exit::ExitStatus;

#[derive(Debug, Serialize)]
struct Run {
    tool: String,
    episodes: usize,
    frames: usize,
    seconds: f64,
    peak_rss_mb: f64,
}

/// Writes `episodes` click_mouse raw episode folders with a `front` H.264 camera (one
/// video encoded, copied into every episode: generation stays quick).
fn generate(dir: &Path, episodes: usize, frames: usize, size: u32) -> anyhow::Result<()> {
    let task = TaskSpec::builtin("click_mouse").context("click_mouse task")?;
    for i in 0..episodes {
        let ep = dexjoco_core::synth::episode(task, frames, i as u64);
        let d = dir.join(&task.id).join(format!("episode_{i:06}"));
        dexjoco_formats::raw::write_replay_zarr(&d, &ep)?;
        let spec = dexjoco_video::VideoSpec {
            width: size,
            height: size,
            fps: 30,
            codec: dexjoco_video::Codec::DEXJOCO,
        };
        fs_err::create_dir_all(d.join("videos"))?;
        if i > 0 {
            let first = dir.join(&task.id).join("episode_000000/videos/front.mp4");
            fs_err::copy(first, d.join("videos/front.mp4"))?;
            continue;
        }
        let mut w = dexjoco_video::VideoWriter::create(d.join("videos/front.mp4"), spec)?;
        let mut frame = vec![0u8; (size * size * 3) as usize];
        for k in 0..frames {
            for (j, px) in frame.iter_mut().enumerate() {
                *px = ((j / 3 + 7 * k + 31 * i) % 251) as u8;
            }
            w.write_frame(&frame)?;
        }
        w.finish()?;
    }
    Ok(())
}

/// Runs `cmd` under `/usr/bin/time`; returns (seconds, peak RSS in MB).
fn timed(program: &Path, args: &[&str]) -> anyhow::Result<(f64, f64, String)> {
    let out = Command::new("/usr/bin/time")
        .arg("-f")
        .arg("BENCH %e %M")
        .arg(program)
        .args(args)
        .output()
        .context("running /usr/bin/time (install the `time` package)")?;
    let stderr = String::from_utf8_lossy(&out.stderr);
    anyhow::ensure!(
        out.status.success(),
        "{} failed ({}):\n{stderr}",
        program.display(),
        out.status
    );
    let line = stderr
        .lines()
        .rev()
        .find(|l| l.starts_with("BENCH "))
        .context("no /usr/bin/time report")?;
    let mut it = line.split_whitespace().skip(1);
    let secs: f64 = it.next().context("elapsed")?.parse()?;
    let kb: f64 = it.next().context("max RSS")?.parse()?;
    Ok((
        secs,
        kb / 1024.0,
        String::from_utf8_lossy(&out.stdout).into_owned(),
    ))
}

fn python() -> anyhow::Result<PathBuf> {
    crate::locate::python().map(|l| l.path).context(
        "no Python with lerobot: run scripts/setup.sh --python in the checkout (or set DEXJOCO_PYTHON)",
    )
}

fn ours(
    tmp: &Path,
    input: &Path,
    name: &str,
    config: &Path,
    episodes: usize,
    frames: usize,
) -> anyhow::Result<Run> {
    let exe = std::env::current_exe()?;
    let out = tmp.join(name);
    let (seconds, peak, _) = timed(
        &exe,
        &[
            "-q",
            "convert",
            &input.to_string_lossy(),
            "--out",
            &out.to_string_lossy(),
            "--config",
            &config.to_string_lossy(),
            "--no-skip-static",
        ],
    )?;
    Ok(Run {
        tool: "dexjoco-data convert (LeRobot v3.0, stream copy)".into(),
        episodes,
        frames,
        seconds,
        peak_rss_mb: peak,
    })
}

/// Runs `bench convert`.
pub fn run(global: &GlobalArgs, args: &BenchConvertArgs) -> anyhow::Result<ExitStatus> {
    let tmp = tempfile::tempdir()?;
    let config = tmp.path().join("selection.toml");
    // The same arrays on both sides: action (23) and the proprioceptive state (23).
    fs_err::write(&config, "[default]\naction = \"action\"\nstate = [0, 23]\n")?;
    let raw = tmp.path().join("raw");
    let pb = crate::progress::bar(1, "generate", global.quiet);
    generate(&raw, args.episodes, args.frames, args.size)?;
    pb.finish_and_clear();
    let mut runs = vec![ours(
        tmp.path(),
        &raw,
        "ours",
        &config,
        args.episodes,
        args.frames,
    )?];
    tracing::info!("ours: {:?}", runs[0]);
    if !args.no_lerobot {
        runs.push(lerobot(tmp.path(), &raw, args)?);
        tracing::info!("lerobot: {:?}", runs[1]);
    }
    let memory = memory_runs(tmp.path(), &config, args)?;
    print_tables(args, &runs, &memory);
    let out = global.work_dir.join("bench");
    fs_err::create_dir_all(&out)?;
    let json = out.join("convert.json");
    fs_err::write(
        &json,
        serde_json::to_string_pretty(&serde_json::json!({ "runs": runs, "memory": memory }))?,
    )?;
    errln!("wrote {}", json.display());
    Ok(ExitStatus::Success)
}

/// lerobot's own writer on the episodes in `raw` (the checkout's
/// `tests/python/bench_lerobot_writer.py`).
fn lerobot(tmp: &Path, raw: &Path, args: &BenchConvertArgs) -> anyhow::Result<Run> {
    let script = crate::locate::checkout()
        .context("bench convert runs lerobot's writer from the source checkout's tests/python: run it from a checkout, or pass --no-lerobot")?
        .join("tests/python/bench_lerobot_writer.py");
    let out = tmp.join("lerobot");
    let (seconds, peak, _) = timed(
        &python()?,
        &[
            &script.to_string_lossy(),
            &raw.to_string_lossy(),
            &out.to_string_lossy(),
            "30",
        ],
    )?;
    Ok(Run {
        tool: "lerobot 0.6.1 LeRobotDataset writer (AV1 encode)".into(),
        episodes: args.episodes,
        frames: args.frames,
        seconds,
        peak_rss_mb: peak,
    })
}

/// Our conversion of each of `--memory-episodes` generated 64 px episode sets.
fn memory_runs(tmp: &Path, config: &Path, args: &BenchConvertArgs) -> anyhow::Result<Vec<Run>> {
    let mut memory = Vec::new();
    for &n in &args.memory_episodes {
        let dir = tmp.join(format!("raw-{n}"));
        generate(&dir, n, args.memory_frames, 64)?;
        memory.push(ours(
            tmp,
            &dir,
            &format!("ours-{n}"),
            config,
            n,
            args.memory_frames,
        )?);
        tracing::info!("memory: {:?}", memory.last());
        fs_err::remove_dir_all(&dir)?;
    }
    Ok(memory)
}

/// The comparison and memory tables, as markdown.
fn print_tables(args: &BenchConvertArgs, runs: &[Run], memory: &[Run]) {
    outln!(
        "Convert {} generated click_mouse episodes x {} frames ({}x{} H.264 camera) to LeRobot v3.0",
        args.episodes,
        args.frames,
        args.size,
        args.size
    );
    outln!();
    outln!("| tool | episodes | seconds | peak RSS MB |");
    outln!("|---|---:|---:|---:|");
    for r in runs {
        outln!(
            "| {} | {} | {:.2} | {:.0} |",
            r.tool,
            r.episodes,
            r.seconds,
            r.peak_rss_mb
        );
    }
    if runs.len() == 2 {
        outln!();
        outln!(
            "lerobot / ours: {:.1}x the wall time, {:.1}x the peak memory",
            runs[1].seconds / runs[0].seconds,
            runs[1].peak_rss_mb / runs[0].peak_rss_mb
        );
    }
    outln!();
    outln!("| our peak memory | episodes | frames each | seconds | peak RSS MB |");
    outln!("|---|---:|---:|---:|---:|");
    for r in memory {
        outln!(
            "| dexjoco-data convert | {} | {} | {:.2} | {:.0} |",
            r.episodes,
            r.frames,
            r.seconds,
            r.peak_rss_mb
        );
    }
}
