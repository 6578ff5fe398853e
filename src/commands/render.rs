//! `dexjoco-data render`: PNGs of a scene's cameras and a contact sheet.

use std::path::Path;

use anyhow::Context;
use dexjoco_core::TaskSpec;
use dexjoco_formats::fs::StagedFiles;
use dexjoco_render::{CameraView, Frame, RenderSettings, Renderer};
use dexjoco_sim::mujoco_rs::prelude::MjData;
use dexjoco_sim::{EnvOptions, SceneSource, TaskEnv, load_task_scene};
use dexjoco_video::{Codec, VideoSpec, VideoWriter};

use crate::exit::ExitStatus;
use crate::settings::RenderCommandSettings;

/// Runs `render`.
pub fn run(command: &RenderCommandSettings) -> anyhow::Result<ExitStatus> {
    if let Some(task) = &command.task {
        return run_task(command, task);
    }
    let scene = super::load_scene(command.scene.as_deref())?;
    let stem = command
        .scene
        .as_deref()
        .and_then(Path::file_stem)
        .map_or_else(
            || "tabletop".to_owned(),
            |s| s.to_string_lossy().into_owned(),
        );
    // Staged and renamed into place at the end; an earlier run's files of the same names
    // are replaced only with --overwrite.
    let mut files = StagedFiles::begin(&command.out, command.overwrite)?;

    let names: Vec<String> = if command.cameras.is_empty() {
        scene.camera_names()
    } else {
        command.cameras.clone()
    };
    let mut views = Vec::new();
    for n in &names {
        views.push((n.clone(), CameraView::Fixed(scene.camera_id(n)?)));
    }
    if views.is_empty() {
        tracing::info!("the scene has no camera: rendering a free view");
        let stat = &scene.model.ffi().stat;
        views.push((
            "free".into(),
            CameraView::Orbit {
                lookat: stat.center,
                distance: 1.5 * stat.extent,
                azimuth: 90.0,
                elevation: -25.0,
            },
        ));
    }

    let settings = command.render;
    let mut renderer = Renderer::new(&scene.model, settings)?;
    tracing::info!(
        "rendering {} camera(s) of {} at {}x{} ({}) on EGL device '{}'{}",
        views.len(),
        scene.path.display(),
        settings.width,
        settings.height,
        settings.quality.name(),
        renderer.device().description,
        renderer
            .device()
            .gl_renderer
            .as_deref()
            .map(|r| format!(" [{r}]"))
            .unwrap_or_default()
    );

    let mut data = MjData::new(&*scene.model);
    data.forward();
    if let Some(fps) = command.video_fps {
        let clip = Clip {
            fps,
            steps: command.steps,
            quiet: command.quiet,
        };
        return video(clip, &mut renderer, &mut data, &views, files, &stem);
    }
    if command.steps > 0 {
        let pb = crate::progress::bar(command.steps as u64, "simulate", command.quiet);
        for _ in 0..command.steps {
            data.step();
            pb.inc(1);
        }
        pb.finish_and_clear();
    }

    let mut frames = Vec::new();
    for (name, view) in &views {
        let frame = renderer.render(&mut data, *view)?;
        save_still(
            &frame,
            &mut files,
            &format!("{stem}_{name}"),
            settings.depth,
        )?;
        frames.push(frame);
    }
    if frames.len() > 1 {
        save_sheet(&frames, &mut files, &format!("{stem}_contact_sheet.png"))?;
    }
    files.publish()?;
    Ok(ExitStatus::Success)
}

/// What `--video` records.
struct Clip {
    /// Frames per second.
    fps: u32,
    /// Physics steps (0: 1000).
    steps: usize,
    /// No progress bar.
    quiet: bool,
}

/// Simulates the clip's steps and streams one frame per 1/fps of simulated time and
/// camera into an H.264 video per camera.
fn video(
    Clip { fps, steps, quiet }: Clip,
    renderer: &mut Renderer,
    data: &mut MjData<&dexjoco_sim::mujoco_rs::prelude::MjModel>,
    views: &[(String, CameraView)],
    mut files: StagedFiles,
    stem: &str,
) -> anyhow::Result<ExitStatus> {
    let steps = if steps == 0 { 1000 } else { steps };
    let timestep = data.model().ffi().opt.timestep;
    let settings = renderer.settings();
    let spec = VideoSpec {
        width: settings.width,
        height: settings.height,
        fps,
        codec: Codec::DEXJOCO,
    };
    let mut writers = Vec::new();
    for (name, _) in views {
        let name = format!("{stem}_{name}.mp4");
        let staged = files.file(&name)?;
        writers.push((VideoWriter::create(&staged, spec)?, files.target(&name)));
    }
    let pb = crate::progress::bar(steps as u64, "video", quiet);
    let mut next_frame = 0.0;
    for step in 0..=steps {
        let t = step as f64 * timestep;
        if t + 1e-12 >= next_frame {
            for ((writer, _), (_, view)) in writers.iter_mut().zip(views) {
                writer.write_frame(&renderer.render(data, *view)?.rgb)?;
            }
            next_frame += 1.0 / f64::from(fps);
        }
        if step < steps {
            data.step();
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    for (writer, path) in writers {
        let frames = writer.finish()?;
        outln!("{} ({frames} frames, {fps} fps, H.264)", path.display());
    }
    files.publish()?;
    Ok(ExitStatus::Success)
}

/// Writes `<name>.png` and, with `depth`, `<name>_depth.png`, each path on stdout (the
/// depth one with its range in metres).
fn save_still(
    frame: &Frame,
    files: &mut StagedFiles,
    name: &str,
    depth: bool,
) -> anyhow::Result<()> {
    let png = format!("{name}.png");
    frame.save_png(&files.file(&png)?)?;
    outln!("{}", files.target(&png).display());
    if depth {
        let dpng = format!("{name}_depth.png");
        if let Some((lo, hi)) = frame.save_depth_png(&files.file(&dpng)?)? {
            outln!(
                "{} (depth {lo:.3} m .. {hi:.3} m)",
                files.target(&dpng).display()
            );
        }
    }
    Ok(())
}

/// Writes a contact sheet of `frames` as `name`, its path on stdout.
fn save_sheet(frames: &[Frame], files: &mut StagedFiles, name: &str) -> anyhow::Result<()> {
    contact_sheet(frames, &files.file(name)?)?;
    outln!("{}", files.target(name).display());
    Ok(())
}

/// Tiles frames of equal size into a grid (at most 4 per row) with a thin border.
pub fn contact_sheet(frames: &[Frame], path: &Path) -> anyhow::Result<()> {
    contact_sheet_in_columns(frames, frames.len().min(4), path)
}

/// Writes `frames` tiled `columns` to a row (4 px white gaps) as `path`.
pub fn contact_sheet_in_columns(
    frames: &[Frame],
    columns: usize,
    path: &Path,
) -> anyhow::Result<()> {
    let tiles = frames
        .iter()
        .map(|f| image::RgbImage::from_raw(f.width, f.height, f.rgb.clone()).context("frame size"))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let layout = dexjoco_render::SheetLayout {
        columns: columns as u32,
        tile: None,
        gap: 4,
        background: [255, 255, 255],
    };
    let sheet = dexjoco_render::contact_sheet(&tiles, layout).context("no frames to tile")?;
    sheet
        .save(path)
        .with_context(|| format!("cannot write '{}'", path.display()))?;
    Ok(())
}

/// Renders a task's scene at its reset state, after `steps` physics steps, from the
/// named cameras.
fn render_task_scene(
    source: &SceneSource,
    spec: &TaskSpec,
    cameras: &[String],
    settings: RenderSettings,
    steps: usize,
) -> anyhow::Result<Vec<Frame>> {
    let scene = load_task_scene(source, spec)?;
    let mut env = TaskEnv::new(&scene, spec, EnvOptions::default())?;
    for _ in 0..steps {
        env.data_mut().step();
    }
    let mut renderer = Renderer::new(&scene.model, settings)?;
    let mut frames = Vec::new();
    for c in cameras {
        let view = CameraView::Fixed(scene.camera_id(c)?);
        let feedback = dexjoco_sim::Feedback::new(spec, &scene.model)?;
        renderer.update_scene(env.data_mut(), view);
        feedback.apply(env.checker(), renderer.scene_mut());
        frames.push(renderer.draw()?);
    }
    Ok(frames)
}

/// `render --task T`: the task's cameras (or those asked for) and their sheet.
fn render_one_task(
    command: &RenderCommandSettings,
    spec: &TaskSpec,
    files: &mut StagedFiles,
) -> anyhow::Result<()> {
    let source = SceneSource::from_option(command.scene_dir.clone());
    let cameras: Vec<String> = if command.cameras.is_empty() {
        spec.cameras.iter().map(|c| c.camera.clone()).collect()
    } else {
        command.cameras.clone()
    };
    let settings = command.render;
    let frames = render_task_scene(&source, spec, &cameras, settings, command.steps)?;
    let kind = if command.scene_dir.is_some() {
        "scene_dir"
    } else {
        "builtin"
    };
    let task = &spec.id;
    for (c, f) in cameras.iter().zip(&frames) {
        save_still(f, files, &format!("{task}_{kind}_{c}"), settings.depth)?;
    }
    if frames.len() > 1 {
        save_sheet(&frames, files, &format!("{task}_{kind}_contact_sheet.png"))?;
    }
    Ok(())
}

/// `render --task T|all`.
fn run_task(command: &RenderCommandSettings, task: &str) -> anyhow::Result<ExitStatus> {
    let specs: Vec<&TaskSpec> = command.tasks.iter().collect();
    let mut files = StagedFiles::begin(&command.out, command.overwrite)?;
    let settings = command.render;
    if task != "all" {
        let Some(spec) = specs.iter().find(|s| s.id == task) else {
            let ids: Vec<_> = specs.iter().map(|s| s.id.as_str()).collect();
            return Err(crate::settings::usage(
                format!("unknown task '{task}'"),
                format!("known tasks: {}, or all", ids.join(", ")),
            ));
        };
        render_one_task(command, spec, &mut files)?;
        files.publish()?;
        return Ok(ExitStatus::Success);
    }

    // Every task: built-in next to reference, same camera.
    let reference = command
        .scene_dir
        .clone()
        .or_else(super::reference_scene_dir);
    if reference.is_none() {
        tracing::warn!("no reference scenes found: the sheet shows the built-in scenes only");
    }
    // A task that fails to render is a dark red tile, named on stderr, and exit code 3.
    let failed_tile = || Frame {
        width: settings.width,
        height: settings.height,
        rgb: [96u8, 0, 0].repeat((settings.width * settings.height) as usize),
        depth: None,
    };
    let mut failures = Vec::new();
    let mut tiles = Vec::new();
    let pb = crate::progress::bar(specs.len() as u64, "render", command.quiet);
    for spec in &specs {
        let camera = command
            .cameras
            .first()
            .cloned()
            .unwrap_or_else(|| spec.cameras[0].camera.clone());
        let cams = [camera.clone()];
        let mut pair = Vec::new();
        let sources = std::iter::once(("builtin", Some(SceneSource::BuiltIn))).chain(
            reference
                .clone()
                .map(|d| ("reference", Some(SceneSource::Dir(d)))),
        );
        for (kind, source) in sources {
            let source = source.expect("some");
            match render_task_scene(&source, spec, &cams, settings, command.steps) {
                Ok(mut f) => {
                    let frame = f.remove(0);
                    let png = format!("{}_{kind}_{camera}.png", spec.id);
                    frame.save_png(&files.file(&png)?)?;
                    if settings.depth {
                        let dpng = format!("{}_{kind}_{camera}_depth.png", spec.id);
                        frame.save_depth_png(&files.file(&dpng)?)?;
                    }
                    pair.push(frame);
                }
                Err(e) => {
                    let why = crate::exit::one_line(&e);
                    tracing::debug!("{} ({kind}): {why}", spec.id);
                    failures.push(format!("{} ({kind} scene): {why}", spec.id));
                    pair.push(failed_tile());
                }
            }
        }
        tiles.extend(pair);
        pb.inc(1);
    }
    pb.finish_and_clear();
    save_sheet(&tiles, &mut files, "tasks_contact_sheet.png")?;
    files.publish()?;
    if failures.is_empty() {
        return Ok(ExitStatus::Success);
    }
    errln!(
        "{} of {} scene(s) could not be rendered (dark red tiles on the sheet):",
        failures.len(),
        tiles.len()
    );
    for f in &failures {
        errln!("  FAILED: {f}");
    }
    Ok(ExitStatus::Partial)
}
