//! `dexjoco-data bench`: performance measurements printed as Markdown tables.

use std::path::PathBuf;
use std::time::Instant;

use dexjoco_render::{CameraView, RenderQuality, RenderSettings, Renderer};
use dexjoco_sim::mujoco_rs::prelude::MjData;
use dexjoco_sim::mujoco_rs::wrappers::mj_model::traits::ModelType;
use serde::Serialize;

use crate::cli::{BenchCommand, GlobalArgs};
use crate::exit::ExitStatus;
use crate::settings::{BenchAugmentSettings, BenchIngestSettings, BenchRenderSettings};

/// Runs a `bench` subcommand.
pub fn run(global: &GlobalArgs, cmd: &BenchCommand) -> anyhow::Result<ExitStatus> {
    match cmd {
        BenchCommand::Render(args) => render(&BenchRenderSettings::resolve(args, global)?),
        BenchCommand::Ingest(args) => ingest(&BenchIngestSettings::resolve(args, global)),
        BenchCommand::Augment(args) => super::bench_augment::run(&BenchAugmentSettings::resolve(
            args,
            global,
            super::augment::sample_data,
        )?),
        BenchCommand::RenderLimit(args) => super::bench_augment::render_limit(global, args),
    }
}

#[derive(Debug, Serialize)]
struct Row {
    scene: String,
    size: u32,
    preset: &'static str,
    geometry: &'static str,
    frames: usize,
    seconds: f64,
    fps: f64,
}

/// Times offscreen rendering of each scene at each size, preset and geometry.
fn render(args: &BenchRenderSettings) -> anyhow::Result<ExitStatus> {
    let scenes = render_scenes(&args.scenes);
    let presets = &args.presets;
    let total = (scenes.len() * args.sizes.len() * presets.len() * args.geometries.len()) as u64;
    let pb = crate::progress::bar(total, "bench", args.quiet);
    let mut rows = Vec::new();
    let mut device = String::new();
    for scene_path in &scenes {
        let scene = super::load_scene(scene_path.as_deref())?;
        let label = scene_path.as_ref().and_then(|p| p.file_stem()).map_or_else(
            || "tabletop (built-in)".to_owned(),
            |s| s.to_string_lossy().into_owned(),
        );
        let cam_names = scene.camera_names();
        let camera = match &args.camera {
            Some(c) => scene.camera_id(c)?,
            None => cam_names.iter().position(|c| c == "front").unwrap_or(0),
        };
        let mut data = MjData::new(&*scene.model);
        data.forward();
        for &size in &args.sizes {
            for (&preset, geometry) in presets
                .iter()
                .flat_map(|p| args.geometries.iter().map(move |&g| (p, g)))
            {
                pb.set_message(format!(
                    "{label} {size}px {} {}",
                    preset.name(),
                    geometry.name()
                ));
                let settings = RenderSettings {
                    width: size,
                    height: size,
                    quality: RenderQuality::from_name(preset.name()).expect("preset"),
                    depth: false,
                    geometry,
                };
                let mut r = Renderer::new(&scene.model, settings)?;
                device = r.device().label();
                let seconds = time_frames(&mut r, &mut data, camera, args.frames)?;
                rows.push(Row {
                    scene: label.clone(),
                    size,
                    preset: preset.name(),
                    geometry: geometry.name(),
                    frames: args.frames,
                    seconds,
                    fps: args.frames as f64 / seconds,
                });
                pb.inc(1);
            }
        }
    }
    pb.finish_and_clear();
    print_render_rows(&rows, &device);
    fs_err::create_dir_all(&args.out)?;
    let json = args.out.join("render.json");
    fs_err::write(
        &json,
        serde_json::to_string_pretty(&serde_json::json!({ "device": device, "rows": rows }))?,
    )?;
    errln!("wrote {}", json.display());
    Ok(ExitStatus::Success)
}

/// The scenes to measure: those given, or the built-in one and (when found) a DexJoCo
/// reference scene.
fn render_scenes(given: &[PathBuf]) -> Vec<Option<PathBuf>> {
    let mut scenes: Vec<Option<PathBuf>> = given.iter().cloned().map(Some).collect();
    if scenes.is_empty() {
        scenes.push(None);
        match super::reference_scene_dir() {
            Some(dir) => scenes.push(Some(dir.join("arena_arm_hand_plant.xml"))),
            None => tracing::warn!(
                "DexJoCo reference scenes not found (../shared/dexjoco-upstream): measuring the built-in scene only"
            ),
        }
    }
    scenes
}

/// Seconds `renderer` takes to render `frames` frames of `camera`, after 3 warm-up frames.
fn time_frames<M: ModelType>(
    renderer: &mut Renderer,
    data: &mut MjData<M>,
    camera: usize,
    frames: usize,
) -> anyhow::Result<f64> {
    for _ in 0..3 {
        renderer.render(data, CameraView::Fixed(camera))?;
    }
    let t = Instant::now();
    for _ in 0..frames {
        renderer.render(data, CameraView::Fixed(camera))?;
    }
    Ok(t.elapsed().as_secs_f64())
}

/// The rendering measurements as a Markdown table.
fn print_render_rows(rows: &[Row], device: &str) {
    outln!(
        "Offscreen rendering, one camera, update scene + draw + read back RGB; device: {device}"
    );
    outln!();
    outln!("| scene | size | preset | geometry | frames/s | ms/frame |");
    outln!("|---|---:|---|---|---:|---:|");
    for r in rows {
        outln!(
            "| {} | {}x{} | {} | {} | {:.1} | {:.1} |",
            r.scene,
            r.size,
            r.size,
            r.preset,
            r.geometry,
            r.fps,
            1000.0 / r.fps
        );
    }
}

#[derive(Debug, Serialize)]
struct IngestRow {
    format: &'static str,
    episodes: usize,
    frames: usize,
    megabytes: f64,
    seconds: f64,
    episodes_per_s: f64,
    mb_per_s: f64,
}

/// Generates `episodes` valid episodes (tasks cycling through all 11) as DexJoCo raw
/// folders and as MCAP files, then times `ingest` of each set into an empty store.
fn ingest(args: &BenchIngestSettings) -> anyhow::Result<ExitStatus> {
    use dexjoco_core::{TaskSet, synth};
    use dexjoco_formats::{discover, mcap, raw};
    use dexjoco_ingest::{IngestOptions, Outcome, Store};

    let tmp = tempfile::tempdir()?;
    let raw_in = tmp.path().join("raw");
    let mcap_in = tmp.path().join("mcap");
    let pb = crate::progress::bar(args.episodes as u64, "generate", args.quiet);
    for i in 0..args.episodes {
        let tasks = TaskSet::builtin();
        let task = tasks.iter().nth(i % tasks.len()).expect("in range");
        let ep = synth::episode(task, args.frames, i as u64);
        let dir = raw_in.join(&task.id).join(format!("episode_{i:06}"));
        raw::write_replay_zarr(&dir, &ep)?;
        mcap::write_episode_mcap(
            &mcap_in.join(format!("{}_{i:06}.mcap", task.id)),
            &ep,
            task,
            &dexjoco_formats::EpisodeMeta::default(),
        )?;
        pb.inc(1);
    }
    pb.finish_and_clear();

    let mut rows = Vec::new();
    for (format, input) in [
        ("DexJoCo raw (zarr)", &raw_in),
        ("MCAP (json, zstd)", &mcap_in),
    ] {
        let store_dir = tmp.path().join(format!("store-{}", rows.len()));
        let mut store = Store::open(&store_dir)?;
        let sources = discover(std::slice::from_ref(input), Some(&store_dir))?;
        let bar = crate::progress::Bar::new("ingest", args.quiet);
        let summary = store.ingest(&sources, &IngestOptions::default(), &bar)?;
        bar.finish();
        let landed = summary.count(Outcome::Landed);
        anyhow::ensure!(
            landed == args.episodes,
            "benchmark episodes were rejected: {landed} of {} landed",
            args.episodes
        );
        let megabytes = summary.bytes_read as f64 / 1e6;
        rows.push(IngestRow {
            format,
            episodes: landed,
            frames: args.frames,
            megabytes,
            seconds: summary.seconds,
            episodes_per_s: landed as f64 / summary.seconds,
            mb_per_s: megabytes / summary.seconds,
        });
    }
    let threads = args.threads;
    outln!(
        "Ingest (read, hash, validate, write Zarr, commit) of {} generated episodes x {} frames, {threads} thread(s)",
        args.episodes,
        args.frames
    );
    outln!();
    outln!("| input | episodes | MB read | seconds | episodes/s | MB/s |");
    outln!("|---|---:|---:|---:|---:|---:|");
    for r in &rows {
        outln!(
            "| {} | {} | {:.1} | {:.2} | {:.1} | {:.1} |",
            r.format,
            r.episodes,
            r.megabytes,
            r.seconds,
            r.episodes_per_s,
            r.mb_per_s
        );
    }
    fs_err::create_dir_all(&args.out)?;
    let json = args.out.join("ingest.json");
    fs_err::write(
        &json,
        serde_json::to_string_pretty(&serde_json::json!({ "threads": threads, "rows": rows }))?,
    )?;
    errln!("wrote {}", json.display());
    Ok(ExitStatus::Success)
}
