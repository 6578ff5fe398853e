//! `dexjoco-data bench convert`: our `convert` against lerobot's own dataset writer and
//! the DexJoCo reference converter (its LeRobot and Zarr entry points, run in place from
//! the reference code beside the checkout) on the same generated episodes (wall time,
//! peak memory of each child process), and our peak memory for few vs many short
//! episodes.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::Context;
use dexjoco_core::TaskSpec;
use serde::Serialize;

use crate::cli::BenchConvertArgs;
use dexjoco_cli::cli::GlobalArgs;
use dexjoco_cli::exit::ExitStatus;

#[derive(Debug, Serialize)]
struct Run {
    tool: String,
    episodes: usize,
    frames: usize,
    seconds: f64,
    peak_rss_mb: f64,
}

impl Run {
    fn new(tool: &str, args: &BenchConvertArgs, (seconds, peak_rss_mb): (f64, f64)) -> Self {
        Self {
            tool: tool.into(),
            episodes: args.episodes,
            frames: args.frames,
            seconds,
            peak_rss_mb,
        }
    }
}

/// A line under the table: run `theirs` against run `ours` (indices into the runs).
struct Ratio {
    label: &'static str,
    theirs: usize,
    ours: usize,
}

/// Our LeRobot v3.0 row's tool.
const OURS_LEROBOT: &str = "dexjoco-data convert (LeRobot v3.0, stream copy)";

/// Writes `episodes` click_mouse raw episode folders with a `front` H.264 camera encoded
/// as augment encodes by default (one video encoded, copied into every episode:
/// generation stays quick).
fn generate(dir: &Path, episodes: usize, frames: usize, size: u32) -> anyhow::Result<()> {
    let task = TaskSpec::builtin("click_mouse").context("click_mouse task")?;
    for i in 0..episodes {
        let ep = dexjoco_core::synth::episode(task, frames, i as u64);
        let d = dir.join(&task.id).join(format!("episode_{i:06}"));
        dexjoco_formats::raw::write_replay_zarr(&d, &ep)?;
        fs_err::create_dir_all(d.join("videos"))?;
        if i > 0 {
            let first = dir.join(&task.id).join("episode_000000/videos/front.mp4");
            fs_err::copy(first, d.join("videos/front.mp4"))?;
            continue;
        }
        // Encoded as augment encodes by default (its keyframe interval decides random reads).
        let encoding = dexjoco_augment::VideoEncoding::default();
        let spec = dexjoco_video::VideoSpec {
            width: size,
            height: size,
            fps: 30,
            codec: encoding.codec(),
        };
        let mut w = dexjoco_video::VideoWriter::create_with(
            d.join("videos/front.mp4"),
            spec,
            &encoding.keyframes(Vec::new()),
        )?;
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
    dexjoco_cli::locate::python().map(|l| l.path).context(
        "no Python with lerobot: run scripts/setup.sh --python in the checkout (or set DEXJOCO_PYTHON)",
    )
}

/// Our conversion of `input` into `tmp/name` (`extra`: more convert flags); returns
/// (seconds, peak RSS MB).
fn ours(
    tmp: &Path,
    input: &Path,
    name: &str,
    config: &Path,
    extra: &[&str],
) -> anyhow::Result<(f64, f64)> {
    let exe = std::env::current_exe()?;
    let out = tmp.join(name);
    let (input, out, config) = (
        input.to_string_lossy(),
        out.to_string_lossy(),
        config.to_string_lossy(),
    );
    let mut argv = vec![
        crate::USER,
        "-q",
        "convert",
        &input,
        "--out",
        &out,
        "--config",
        &config,
        "--no-skip-static",
    ];
    argv.extend_from_slice(extra);
    let (seconds, peak, _) = timed(&exe, &argv)?;
    Ok((seconds, peak))
}

/// Runs `bench convert`.
pub fn run(global: &GlobalArgs, args: &BenchConvertArgs) -> anyhow::Result<ExitStatus> {
    let tmp = tempfile::tempdir()?;
    let config = tmp.path().join("selection.toml");
    // The same arrays on every side: action (23) and the proprioceptive state (23).
    fs_err::write(&config, "[default]\naction = \"action\"\nstate = [0, 23]\n")?;
    let raw = tmp.path().join("raw");
    let pb = dexjoco_cli::progress::bar(1, "generate", global.quiet);
    generate(&raw, args.episodes, args.frames, args.size)?;
    pb.finish_and_clear();
    let ours_lerobot = ours(tmp.path(), &raw, "ours", &config, &[])?;
    let mut runs = vec![Run::new(OURS_LEROBOT, args, ours_lerobot)];
    tracing::info!("ours: {:?}", runs[0]);
    let mut ratios = Vec::new();
    if !args.no_lerobot {
        runs.push(lerobot(tmp.path(), &raw, args)?);
        tracing::info!("lerobot: {:?}", runs[1]);
        ratios.push(Ratio {
            label: "lerobot's writer / ours (LeRobot v3.0)",
            theirs: 1,
            ours: 0,
        });
    }
    let reference = if args.no_reference {
        Err("--no-reference".to_owned())
    } else {
        reference_code()
    };
    match &reference {
        Ok(code) => reference_runs(
            tmp.path(),
            &raw,
            &config,
            args,
            code,
            &mut runs,
            &mut ratios,
        )?,
        Err(why) => outln!("DexJoCo reference converter: skipped ({why})"),
    }
    let memory = memory_runs(tmp.path(), &config, args)?;
    let reads = random_reads(tmp.path(), args, reference.is_ok())?;
    print_tables(args, &runs, &ratios, &memory);
    print_reads(&reads);
    let out = global.work_dir.join("bench");
    fs_err::create_dir_all(&out)?;
    let json = out.join("convert.json");
    let skipped = reference.err();
    fs_err::write(
        &json,
        serde_json::to_string_pretty(&serde_json::json!({
            "runs": runs,
            "memory": memory,
            "random_reads": reads,
            "reference_converter_skipped": skipped,
        }))?,
    )?;
    errln!("wrote {}", json.display());
    Ok(ExitStatus::Success)
}

/// The DexJoCo reference converter's code, found in place.
struct ReferenceCode {
    /// `dexjoco-data-converter/src` (the `dexjoco_data_converter` package).
    converter_src: PathBuf,
    /// The folder of Diffusion Policy's `replay_buffer.py` (its Zarr writer imports it).
    diffusion_policy: PathBuf,
    /// `tests/python/reference_converter.py` of the checkout, which runs it.
    driver: PathBuf,
}

/// The reference code: `$DEXJOCO_THIRD_PARTY`, else `../shared/third_party` beside the
/// checkout; Diffusion Policy from `$DEXJOCO_DIFFUSION_POLICY`, else the checkout's
/// `.deps/diffusion-policy-path`. Err says what is missing.
fn reference_code() -> Result<ReferenceCode, String> {
    let checkout = dexjoco_cli::locate::checkout().ok_or("not run from a source checkout")?;
    let third_party = std::env::var_os("DEXJOCO_THIRD_PARTY")
        .map_or_else(|| checkout.join("../shared/third_party"), PathBuf::from);
    let converter_src = third_party.join("dexjoco-8d23b0f/dexjoco-data-converter/src");
    if !converter_src
        .join("dexjoco_data_converter/cli.py")
        .is_file()
    {
        return Err(format!(
            "its code is absent: no {} (looked in $DEXJOCO_THIRD_PARTY, else ../shared/third_party beside the checkout)",
            converter_src.display()
        ));
    }
    let recorded = checkout.join(".deps/diffusion-policy-path");
    let diffusion_policy = std::env::var_os("DEXJOCO_DIFFUSION_POLICY").map_or_else(
        || PathBuf::from(fs_err::read_to_string(&recorded).unwrap_or_default().trim()),
        PathBuf::from,
    );
    if !diffusion_policy
        .join("diffusion_policy/common/replay_buffer.py")
        .is_file()
    {
        return Err(format!(
            "Diffusion Policy's replay_buffer.py is absent (DEXJOCO_DIFFUSION_POLICY, {}): run scripts/setup.sh --python",
            recorded.display()
        ));
    }
    Ok(ReferenceCode {
        converter_src,
        diffusion_policy,
        driver: checkout.join("tests/python/reference_converter.py"),
    })
}

/// The reference converter's LeRobot and Zarr entry points on the generated episodes,
/// with our Diffusion Policy conversion beside the Zarr one (videos stream-copied, as
/// the reference copies them when nothing is trimmed).
fn reference_runs(
    tmp: &Path,
    raw: &Path,
    config: &Path,
    args: &BenchConvertArgs,
    code: &ReferenceCode,
    runs: &mut Vec<Run>,
    ratios: &mut Vec<Ratio>,
) -> anyhow::Result<()> {
    let task = TaskSpec::builtin("click_mouse").context("click_mouse task")?;
    let selected = "{action: action, state: state, cameras: {front: front}}";
    let lerobot_flags = [
        "--language-instruction",
        task.prompt.as_str(),
        "--selected-data-yaml",
        selected,
    ];
    let reference_lerobot =
        run_reference(tmp, raw, code, "dexjoco-dc-single-lerobot", &lerobot_flags)?;
    runs.push(Run::new(
        "DexJoCo reference converter, dexjoco-dc-single-lerobot (decode, AV1 encode)",
        args,
        reference_lerobot,
    ));
    ratios.push(Ratio {
        label: "reference converter / ours (LeRobot v3.0)",
        theirs: runs.len() - 1,
        ours: 0,
    });
    let dp = [
        "--format",
        "diffusion-policy",
        "--videos",
        "--video-codec",
        "h264",
    ];
    let ours_dp = ours(tmp, raw, "ours-dp", config, &dp)?;
    runs.push(Run::new(
        "dexjoco-data convert --format diffusion-policy --videos (frames decoded into the store, videos copied)",
        args,
        ours_dp,
    ));
    let reference_zarr = run_reference(tmp, raw, code, "dexjoco-dc-single-zarr", &[])?;
    runs.push(Run::new(
        "DexJoCo reference converter, dexjoco-dc-single-zarr (arrays, videos copied)",
        args,
        reference_zarr,
    ));
    ratios.push(Ratio {
        label: "reference converter / ours (Diffusion Policy)",
        theirs: runs.len() - 1,
        ours: runs.len() - 2,
    });
    tracing::info!("reference converter: {:?}", &runs[runs.len() - 3..]);
    Ok(())
}

/// One reference console script on the click_mouse episodes in `raw` (state sliced to
/// the proprioceptive 23, static frames kept, as on our side); (seconds, peak RSS MB).
fn run_reference(
    tmp: &Path,
    raw: &Path,
    code: &ReferenceCode,
    entry: &str,
    flags: &[&str],
) -> anyhow::Result<(f64, f64)> {
    let s = |p: &Path| p.to_string_lossy().into_owned();
    let (driver, src, dp) = (
        s(&code.driver),
        s(&code.converter_src),
        s(&code.diffusion_policy),
    );
    let (input, out) = (s(&raw.join("click_mouse")), s(&tmp.join(entry)));
    let mut argv = vec![
        driver.as_str(),
        "run",
        "--code",
        &src,
        "--diffusion-policy",
        &dp,
        entry,
        "--input",
        &input,
        "--output",
        &out,
        "--slice-yaml",
        "{state: [null, 23]}",
        "--no-skip-static-frames",
    ];
    argv.extend_from_slice(flags);
    let (seconds, peak, _) = timed(&python()?, &argv)?;
    Ok((seconds, peak))
}

/// lerobot's own writer on the episodes in `raw` (the checkout's
/// `tests/python/bench_lerobot_writer.py`).
fn lerobot(tmp: &Path, raw: &Path, args: &BenchConvertArgs) -> anyhow::Result<Run> {
    let script = dexjoco_cli::locate::checkout()
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
    Ok(Run::new(
        "lerobot 0.6.1 LeRobotDataset writer (AV1 encode)",
        args,
        (seconds, peak),
    ))
}

/// Our conversion of each of `--memory-episodes` generated 64 px episode sets.
fn memory_runs(tmp: &Path, config: &Path, args: &BenchConvertArgs) -> anyhow::Result<Vec<Run>> {
    let mut memory = Vec::new();
    for &n in &args.memory_episodes {
        let dir = tmp.join(format!("raw-{n}"));
        generate(&dir, n, args.memory_frames, 64)?;
        let (seconds, peak_rss_mb) = ours(tmp, &dir, &format!("ours-{n}"), config, &[])?;
        memory.push(Run {
            tool: OURS_LEROBOT.into(),
            episodes: n,
            frames: args.memory_frames,
            seconds,
            peak_rss_mb,
        });
        tracing::info!("memory: {:?}", memory.last());
        fs_err::remove_dir_all(&dir)?;
    }
    Ok(memory)
}

/// The comparison and memory tables, as markdown.
fn print_tables(args: &BenchConvertArgs, runs: &[Run], ratios: &[Ratio], memory: &[Run]) {
    outln!(
        "Convert {} generated click_mouse episodes x {} frames ({}x{} H.264 camera)",
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
    if !ratios.is_empty() {
        outln!();
    }
    for r in ratios {
        let (theirs, ours) = (&runs[r.theirs], &runs[r.ours]);
        outln!(
            "{}: {:.1}x the wall time, {:.1}x the peak memory",
            r.label,
            theirs.seconds / ours.seconds,
            theirs.peak_rss_mb / ours.peak_rss_mb
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

/// Random-access read time of one LeRobot v3.0 dataset with one video backend.
#[derive(Debug, Serialize)]
struct RandomRead {
    dataset: &'static str,
    backend: &'static str,
    items: usize,
    ms_median: f64,
    ms_mean: f64,
    bytes: u64,
}

/// The folder holding `meta/info.json` at or below `dir` (the reference converter writes
/// its dataset one level down).
fn dataset_root(dir: &Path) -> Option<PathBuf> {
    if dir.join("meta/info.json").is_file() {
        return Some(dir.to_path_buf());
    }
    fs_err::read_dir(dir)
        .ok()?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .find(|p| p.join("meta/info.json").is_file())
}

/// Our LeRobot v3.0 dataset and the reference converter's (when it ran), each read at
/// `args.read_items` seeded random indices with torchcodec and with pyav by lerobot's
/// own LeRobotDataset (`tests/python/lerobot_random_read.py` of the checkout).
fn random_reads(
    tmp: &Path,
    args: &BenchConvertArgs,
    reference_ran: bool,
) -> anyhow::Result<Vec<RandomRead>> {
    if args.read_items == 0 {
        return Ok(Vec::new());
    }
    let script = dexjoco_cli::locate::checkout()
        .context("the read timing runs tests/python/lerobot_random_read.py from the source checkout: run it from a checkout, or pass --read-items 0")?
        .join("tests/python/lerobot_random_read.py");
    let mut datasets = vec![("dexjoco-data convert (stream copy)", tmp.join("ours"))];
    if reference_ran {
        let dir = tmp.join("dexjoco-dc-single-lerobot");
        let root = dataset_root(&dir)
            .with_context(|| format!("no LeRobot dataset under {}", dir.display()))?;
        datasets.push(("DexJoCo reference converter (AV1, GOP 2)", root));
    }
    let python = python()?;
    let mut reads = Vec::new();
    for (dataset, root) in datasets {
        for backend in ["torchcodec", "pyav"] {
            let items = args.read_items.to_string();
            let argv = [
                script.to_string_lossy().into_owned(),
                root.to_string_lossy().into_owned(),
                backend.to_owned(),
                items,
            ];
            let out = Command::new(&python)
                .args(&argv)
                .output()
                .context("running lerobot_random_read.py")?;
            anyhow::ensure!(
                out.status.success(),
                "lerobot_random_read.py failed on {} ({}):\n{}",
                root.display(),
                out.status,
                String::from_utf8_lossy(&out.stderr)
            );
            let stdout = String::from_utf8_lossy(&out.stdout);
            let r: serde_json::Value = serde_json::from_str(stdout.trim())
                .with_context(|| format!("lerobot_random_read.py printed no JSON: {stdout}"))?;
            reads.push(RandomRead {
                dataset,
                backend,
                items: args.read_items,
                ms_median: r["ms_median"].as_f64().unwrap_or(f64::NAN),
                ms_mean: r["ms_mean"].as_f64().unwrap_or(f64::NAN),
                bytes: r["bytes"].as_u64().unwrap_or(0),
            });
        }
    }
    Ok(reads)
}

/// The read-time table.
fn print_reads(reads: &[RandomRead]) {
    if reads.is_empty() {
        return;
    }
    outln!();
    outln!("| LeRobot v3.0 dataset | backend | MB | ms per random item (median) | mean |");
    outln!("|---|---|---:|---:|---:|");
    for r in reads {
        outln!(
            "| {} | {} | {:.1} | {:.1} | {:.1} |",
            r.dataset,
            r.backend,
            r.bytes as f64 / 1e6,
            r.ms_median,
            r.ms_mean
        );
    }
}
