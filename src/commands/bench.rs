//! `dexjoco-data bench`: performance measurements printed as Markdown tables.

use std::path::PathBuf;
use std::time::Instant;

use dexjoco_sim::mujoco_rs::prelude::MjData;
use dexjoco_sim::{CameraView, RenderQuality, RenderSettings, Renderer};
use serde::Serialize;

use crate::cli::{BenchCommand, BenchRenderArgs, GlobalArgs, QualityArg};
use crate::exit::ExitStatus;

/// Runs a `bench` subcommand.
pub fn run(global: &GlobalArgs, cmd: &BenchCommand) -> anyhow::Result<ExitStatus> {
    match cmd {
        BenchCommand::Render(args) => render(global, args),
    }
}

#[derive(Debug, Serialize)]
struct Row {
    scene: String,
    size: u32,
    preset: &'static str,
    frames: usize,
    seconds: f64,
    fps: f64,
}

fn render(global: &GlobalArgs, args: &BenchRenderArgs) -> anyhow::Result<ExitStatus> {
    let mut scenes: Vec<Option<PathBuf>> = args.scenes.iter().cloned().map(Some).collect();
    if scenes.is_empty() {
        scenes.push(None);
        match super::reference_scene_dir() {
            Some(dir) => scenes.push(Some(dir.join("arena_arm_hand_plant.xml"))),
            None => tracing::warn!(
                "DexJoCo reference scenes not found (../shared/dexjoco-upstream): measuring the built-in scene only"
            ),
        }
    }
    let presets: Vec<QualityArg> = if args.presets.is_empty() {
        vec![
            QualityArg::Paper,
            QualityArg::NoMsaa,
            QualityArg::NoMsaaNoShadows,
            QualityArg::Fast,
        ]
    } else {
        args.presets.clone()
    };
    let total = (scenes.len() * args.sizes.len() * presets.len()) as u64;
    let pb = crate::progress::bar(total, "bench", global.quiet);
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
            for &preset in &presets {
                pb.set_message(format!("{label} {size}px {}", preset.name()));
                let settings = RenderSettings {
                    width: size,
                    height: size,
                    quality: RenderQuality::from_name(preset.name()).expect("preset"),
                    depth: false,
                };
                let mut r = Renderer::new(&scene.model, settings)?;
                device = format!(
                    "{} ({})",
                    r.device().gl_renderer.as_deref().unwrap_or("unknown GL"),
                    if r.device().software {
                        "software"
                    } else {
                        "GPU"
                    }
                );
                for _ in 0..3 {
                    r.render(&mut data, CameraView::Fixed(camera))?;
                }
                let t = Instant::now();
                for _ in 0..args.frames {
                    r.render(&mut data, CameraView::Fixed(camera))?;
                }
                let seconds = t.elapsed().as_secs_f64();
                rows.push(Row {
                    scene: label.clone(),
                    size,
                    preset: preset.name(),
                    frames: args.frames,
                    seconds,
                    fps: args.frames as f64 / seconds,
                });
                pb.inc(1);
            }
        }
    }
    pb.finish_and_clear();

    println!(
        "Offscreen rendering, one camera, update scene + draw + read back RGB; device: {device}"
    );
    println!();
    println!("| scene | size | preset | frames/s | ms/frame |");
    println!("|---|---:|---|---:|---:|");
    for r in &rows {
        println!(
            "| {} | {}x{} | {} | {:.1} | {:.1} |",
            r.scene,
            r.size,
            r.size,
            r.preset,
            r.fps,
            1000.0 / r.fps
        );
    }
    let out = global.work_dir.join("bench");
    fs_err::create_dir_all(&out)?;
    let json = out.join("render.json");
    fs_err::write(
        &json,
        serde_json::to_string_pretty(&serde_json::json!({ "device": device, "rows": rows }))?,
    )?;
    eprintln!("wrote {}", json.display());
    Ok(ExitStatus::Success)
}
