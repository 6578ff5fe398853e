//! `dexjoco-data bench fidelity`: the Warp batch renderer against MuJoCo's OpenGL one on
//! each task's scene. The same reset state, randomized looks (camera pose, lights, table)
//! and task cameras drawn by both; PSNR and SSIM per task and camera, a table on stdout,
//! JSON and side-by-side pictures (OpenGL | Warp | difference x4) under
//! `<work-dir>/bench/fidelity/`.

use std::path::Path;

use anyhow::Context;
use dexjoco_core::{TaskSet, TaskSpec};
use dexjoco_render::compare::{Fidelity, compare};
use dexjoco_render::randomize::{
    CameraPool, TABLE_GEOM, TableLibrary, VisualSample, apply_visuals, warp_world,
};
use dexjoco_render::warp::{SceneXml, WarpBatch, WarpRenderer, WarpWorker, view_fovy, view_slots};
use dexjoco_render::{CameraView, Frame, Renderer};
use dexjoco_sim::{EnvOptions, SceneSource, TaskEnv, load_task_scene};
use serde::Serialize;

use crate::cli::BenchFidelityArgs;
use dexjoco_cli::cli::GlobalArgs;
use dexjoco_cli::exit::ExitStatus;

/// One task camera's comparison over its views.
#[derive(Debug, Serialize)]
struct Row {
    task: String,
    camera: String,
    views: usize,
    psnr_mean: f64,
    psnr_min: f64,
    ssim_mean: f64,
    ssim_min: f64,
    mean_abs: f64,
}

/// Runs `bench fidelity`.
pub fn run(global: &GlobalArgs, args: &BenchFidelityArgs) -> anyhow::Result<ExitStatus> {
    let BenchFidelityArgs {
        tasks,
        scene_dir,
        size,
        quality,
        views,
        warp,
    } = args;
    let source = SceneSource::from_option(
        scene_dir
            .clone()
            .or_else(dexjoco_cli::commands::reference_scene_dir),
    );
    let settings = dexjoco_render::RenderSettings {
        depth: false,
        ..dexjoco_cli::settings::render_settings(*size, *quality)
    };
    let options = warp.clone().options();
    let specs: Vec<&TaskSpec> = if tasks.is_empty() {
        TaskSet::builtin().iter().collect()
    } else {
        tasks
            .iter()
            .map(|t| TaskSpec::builtin(t).with_context(|| format!("unknown task '{t}'")))
            .collect::<anyhow::Result<_>>()?
    };
    let out = global.work_dir.join("bench/fidelity");
    fs_err::create_dir_all(&out)?;
    let mut rows = Vec::new();
    let mut sheet = Vec::new();
    let pb = dexjoco_cli::progress::bar(specs.len() as u64, "fidelity", global.quiet);
    for spec in specs {
        let pairs = render_both(&source, spec, settings, &options, *views, global.seed)
            .with_context(|| format!("task {}", spec.id))?;
        rows.extend(summarize(&spec.id, &pairs));
        save_pairs(&pairs, &out.join(format!("{}.png", spec.id)))?;
        if let Some((_, gl, wp)) = pairs.first() {
            sheet.extend([gl.clone(), wp.clone()]);
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    let sheet_path = out.join("sheet.png");
    dexjoco_cli::commands::render::contact_sheet(&sheet, &sheet_path)?;
    print_table(&rows, &source, settings);
    let json = out.join("fidelity.json");
    fs_err::write(&json, serde_json::to_string_pretty(&rows)?)?;
    outln!(
        "\npictures: {}/<task>.png (OpenGL | Warp | difference x4 per view), {}; JSON: {}",
        out.display(),
        sheet_path.display(),
        json.display()
    );
    Ok(ExitStatus::Success)
}

/// (camera name, OpenGL frame, Warp frame) of every view of the task's reset state.
type Pairs = Vec<(String, Frame, Frame)>;

fn render_both(
    source: &SceneSource,
    spec: &TaskSpec,
    settings: dexjoco_render::RenderSettings,
    options: &dexjoco_render::warp::WarpOptions,
    views: usize,
    seed: u64,
) -> anyhow::Result<Pairs> {
    let scene = load_task_scene(source, spec)?;
    let model = &scene.model;
    let mut env = TaskEnv::new(&scene, spec, EnvOptions::default())?;
    let table = TableLibrary::of_model(model, TABLE_GEOM)?;
    let pool = CameraPool::for_task(None, source, spec.setup)?;
    let nlight = model.ffi().nlight as usize;
    let mut wanted: Vec<(String, CameraView, VisualSample)> = Vec::new();
    for v in 0..views {
        let sample = VisualSample::sample(seed + v as u64, &pool, &table, nlight);
        wanted.push(("third_person".into(), sample.camera.view(), sample));
    }
    let first = wanted[0].2.clone();
    for c in &spec.cameras {
        let view = CameraView::Fixed(scene.camera_id(&c.camera)?);
        wanted.push((c.camera.clone(), view, first.clone()));
    }
    let mut gl = Renderer::new(model, settings)?;
    let xml = match source {
        SceneSource::BuiltIn => SceneXml::Text(dexjoco_sim::builtin::scene_xml(spec)?),
        SceneSource::Dir(_) => SceneXml::Path(scene.path.clone()),
    };
    let slots = view_slots(model, wanted.iter().map(|(_, v, _)| *v));
    let worker = WarpWorker::start(options)?;
    let mut warp = WarpRenderer::open(worker, &xml, model, settings, 1, table.geom, &slots)?;
    let mut pairs = Vec::new();
    for (name, view, sample) in wanted {
        gl.update_scene(env.data_mut(), view);
        apply_visuals(&mut gl, &sample, &table);
        let a = gl.draw()?;
        let mut batch = WarpBatch::new(warp.slot_of(view_fovy(model, view))?);
        let data = env.data();
        let f = batch.push_frame(data);
        batch.push_world(f, warp_world(model, data, view, &sample, &table));
        let b = warp.render(&batch)?.pop().context("no image")?;
        pairs.push((name, a, b));
    }
    Ok(pairs)
}

fn summarize(task: &str, pairs: &Pairs) -> Vec<Row> {
    let mut cameras: Vec<&str> = Vec::new();
    for (c, _, _) in pairs {
        if !cameras.contains(&c.as_str()) {
            cameras.push(c);
        }
    }
    cameras
        .into_iter()
        .map(|camera| {
            let f: Vec<Fidelity> = pairs
                .iter()
                .filter(|(c, _, _)| c == camera)
                .map(|(_, a, b)| compare(a, b))
                .collect();
            let n = f.len() as f64;
            let finite = |v: f64| if v.is_finite() { v } else { 99.0 };
            Row {
                task: task.to_owned(),
                camera: camera.to_owned(),
                views: f.len(),
                psnr_mean: f.iter().map(|x| finite(x.psnr)).sum::<f64>() / n,
                psnr_min: f.iter().map(|x| finite(x.psnr)).fold(f64::MAX, f64::min),
                ssim_mean: f.iter().map(|x| x.ssim).sum::<f64>() / n,
                ssim_min: f.iter().map(|x| x.ssim).fold(f64::MAX, f64::min),
                mean_abs: f.iter().map(|x| x.mean_abs).sum::<f64>() / n,
            }
        })
        .collect()
}

/// One row per view: OpenGL, Warp, and their absolute difference times four.
fn save_pairs(pairs: &Pairs, path: &Path) -> anyhow::Result<()> {
    let mut tiles = Vec::new();
    for (_, a, b) in pairs {
        let diff: Vec<u8> = a
            .rgb
            .iter()
            .zip(&b.rgb)
            .map(|(x, y)| (x.abs_diff(*y) as u16 * 4).min(255) as u8)
            .collect();
        tiles.extend([
            a.clone(),
            b.clone(),
            Frame {
                rgb: diff,
                ..a.clone()
            },
        ]);
    }
    dexjoco_cli::commands::render::contact_sheet_in_columns(&tiles, 3, path)
}

fn print_table(rows: &[Row], source: &SceneSource, settings: dexjoco_render::RenderSettings) {
    let scenes = match source {
        SceneSource::BuiltIn => "built-in scenes".to_owned(),
        SceneSource::Dir(d) => d.display().to_string(),
    };
    outln!(
        "Warp vs OpenGL, {}x{} {} ({scenes}):",
        settings.width,
        settings.height,
        settings.quality.name()
    );
    outln!(
        "{:<24} {:<16} {:>5} {:>16} {:>16} {:>9}",
        "task",
        "camera",
        "views",
        "PSNR dB mean/min",
        "SSIM mean/min",
        "mean |d|"
    );
    for r in rows {
        outln!(
            "{:<24} {:<16} {:>5} {:>9.1} / {:>4.1} {:>9.3} / {:.3} {:>9.2}",
            r.task,
            r.camera,
            r.views,
            r.psnr_mean,
            r.psnr_min,
            r.ssim_mean,
            r.ssim_min,
            r.mean_abs
        );
    }
}
