//! `dexjoco-data cameras`: a third-person camera pose pool for a task, built the DexJoCo
//! paper's way (uniform on a sphere, least occluded kept).

use std::path::{Path, PathBuf};

use anyhow::Context;
use dexjoco_augment::build_pool;
use dexjoco_formats::fs::StagedFiles;
use dexjoco_render::{RenderQuality, RenderSettings, Renderer};
use dexjoco_sim::{EnvOptions, TaskEnv, load_task_scene};

use crate::cli::{CamerasArgs, GlobalArgs};
use crate::exit::{CliError, ExitStatus};
use crate::settings::CamerasSettings;

/// Runs `cameras`.
pub fn run(global: &GlobalArgs, args: CamerasArgs) -> anyhow::Result<ExitStatus> {
    let CamerasSettings {
        task: spec,
        scene,
        options,
        out,
        preview,
        overwrite,
    } = CamerasSettings::resolve(args, global)?;
    let spec = &spec;
    // Staged beside the pool file and renamed into place at the end; an earlier run's
    // files are refused now, before the poses are scored, unless --overwrite.
    let file_name = |path: &Path| {
        path.file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned()
    };
    let dir = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let mut files = StagedFiles::begin(dir, overwrite)?;
    let staged_pool = files.file(&file_name(&out))?;
    let sheet = preview_path(&out);
    let staged_sheet = if preview {
        Some(files.file(&file_name(&sheet))?)
    } else {
        None
    };
    let scene = load_task_scene(&scene, spec)
        .with_context(|| format!("loading the scene of '{}'", spec.id))?;
    let bar = crate::progress::bar(0, "scoring poses", global.quiet);
    bar.set_message(format!("{} candidates", options.candidates));
    let built = build_pool(&scene, spec, &options).map_err(|e| CliError {
        message: e.to_string(),
        hint: None,
        status: ExitStatus::Usage,
    })?;
    bar.finish_and_clear();
    fs_err::write(&staged_pool, built.to_json().as_bytes())
        .with_context(|| format!("writing {}", out.display()))?;

    let stats = |v: &mut dyn Iterator<Item = f64>| {
        let v: Vec<f64> = v.collect();
        let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
        let min = v.iter().copied().fold(f64::INFINITY, f64::min);
        let max = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (min, mean, max)
    };
    let all = stats(&mut built.candidates.iter().map(|c| c.occlusion));
    let kept = stats(&mut built.kept.iter().map(|c| c.occlusion));
    outln!(
        "{}: {} of {} poses kept ({} target points on {})",
        spec.id,
        built.kept.len(),
        built.candidates.len(),
        built.targets,
        built.target_bodies.join(", ")
    );
    outln!();
    outln!("| poses | occluded fraction min | mean | max |");
    outln!("|---|---:|---:|---:|");
    outln!(
        "| kept ({}) | {:.3} | {:.3} | {:.3} |",
        built.kept.len(),
        kept.0,
        kept.1,
        kept.2
    );
    outln!(
        "| all candidates ({}) | {:.3} | {:.3} | {:.3} |",
        built.candidates.len(),
        all.0,
        all.1,
        all.2
    );
    if let Some(staged_sheet) = &staged_sheet {
        write_preview(&scene, spec, &built, staged_sheet)?;
    }
    files
        .publish()
        .with_context(|| format!("renaming {} into place", out.display()))?;
    outln!();
    outln!("pool: {}", out.display());
    if preview {
        outln!("preview: {}", sheet.display());
    }
    Ok(ExitStatus::Success)
}

/// `<out without extension>_preview.png`.
fn preview_path(out: &Path) -> PathBuf {
    let stem = out.with_extension("");
    stem.with_file_name(format!(
        "{}_preview.png",
        stem.file_name().unwrap_or_default().to_string_lossy()
    ))
}

/// A contact sheet of up to 16 kept views, at `path`.
fn write_preview(
    scene: &dexjoco_sim::Scene,
    spec: &dexjoco_core::TaskSpec,
    built: &dexjoco_augment::BuiltPool,
    path: &Path,
) -> anyhow::Result<()> {
    let mut env = TaskEnv::new(scene, spec, EnvOptions::default())?;
    let mut r = Renderer::new(
        &scene.model,
        RenderSettings {
            width: 240,
            height: 240,
            quality: RenderQuality::FAST,
            depth: false,
            geometry: dexjoco_render::Geometry::Full,
        },
    )?;
    let n = built.kept.len();
    let picks: Vec<usize> = (0..n.min(16)).map(|i| i * n / n.min(16)).collect();
    let mut frames = Vec::with_capacity(picks.len());
    for i in picks {
        frames.push(r.render(env.data_mut(), built.kept[i].pose.view())?);
    }
    super::render::contact_sheet(&frames, path)
}
