//! `dexjoco-data render`: PNGs of a scene's cameras and a contact sheet.

use std::path::{Path, PathBuf};

use anyhow::Context;
use dexjoco_core::{TaskSet, TaskSpec};
use dexjoco_sim::mujoco_rs::prelude::MjData;
use dexjoco_sim::{
    CameraView, EnvOptions, Frame, RenderQuality, RenderSettings, Renderer, SceneSource, TaskEnv,
    load_task_scene,
};
use dexjoco_video::{Codec, VideoSpec, VideoWriter};

use crate::cli::{GlobalArgs, RenderArgs};
use crate::exit::ExitStatus;

/// Runs `render`.
pub fn run(global: &GlobalArgs, args: &RenderArgs) -> anyhow::Result<ExitStatus> {
    if let Some(task) = &args.task {
        return run_task(global, args, task);
    }
    let scene = super::load_scene(args.scene.as_deref())?;
    let stem = args.scene.as_deref().and_then(Path::file_stem).map_or_else(
        || "tabletop".to_owned(),
        |s| s.to_string_lossy().into_owned(),
    );
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| global.work_dir.join("render"));
    fs_err::create_dir_all(&out)?;

    let names: Vec<String> = if args.cameras.is_empty() {
        scene.camera_names()
    } else {
        args.cameras.clone()
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

    let settings = RenderSettings {
        width: args.width.unwrap_or(args.size),
        height: args.height.unwrap_or(args.size),
        quality: RenderQuality::from_name(args.quality.name())
            .expect("every QualityArg is a preset"),
        depth: args.depth,
        geometry: args.geometry.geometry(),
    };
    let mut renderer = Renderer::new(&scene.model, settings)?;
    tracing::info!(
        "rendering {} camera(s) of {} at {}x{} ({}) on EGL device '{}'{}",
        views.len(),
        scene.path.display(),
        settings.width,
        settings.height,
        args.quality.name(),
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
    if args.video {
        return video(global, args, &mut renderer, &mut data, &views, &out, &stem);
    }
    if args.steps > 0 {
        let pb = crate::progress::bar(args.steps as u64, "simulate", global.quiet);
        for _ in 0..args.steps {
            data.step();
            pb.inc(1);
        }
        pb.finish_and_clear();
    }

    let mut frames = Vec::new();
    for (name, view) in &views {
        let frame = renderer.render(&mut data, *view)?;
        let png = out.join(format!("{stem}_{name}.png"));
        frame.save_png(&png)?;
        outln!("{}", png.display());
        if args.depth {
            let dpng = out.join(format!("{stem}_{name}_depth.png"));
            if let Some((lo, hi)) = frame.save_depth_png(&dpng)? {
                outln!("{} (depth {lo:.3} m .. {hi:.3} m)", dpng.display());
            }
        }
        frames.push(frame);
    }
    if frames.len() > 1 {
        let sheet = out.join(format!("{stem}_contact_sheet.png"));
        contact_sheet(&frames, &sheet)?;
        outln!("{}", sheet.display());
    }
    Ok(ExitStatus::Success)
}

/// Simulates `--steps` steps and streams one frame per 1/fps of simulated time and
/// camera into an H.264 video per camera.
fn video(
    global: &GlobalArgs,
    args: &RenderArgs,
    renderer: &mut Renderer,
    data: &mut MjData<&dexjoco_sim::mujoco_rs::prelude::MjModel>,
    views: &[(String, CameraView)],
    out: &Path,
    stem: &str,
) -> anyhow::Result<ExitStatus> {
    anyhow::ensure!(args.fps > 0, "--fps must be positive");
    let steps = if args.steps == 0 { 1000 } else { args.steps };
    let timestep = data.model().ffi().opt.timestep;
    let settings = renderer.settings();
    let spec = VideoSpec {
        width: settings.width,
        height: settings.height,
        fps: args.fps,
        codec: Codec::DEXJOCO,
    };
    let mut writers = Vec::new();
    for (name, _) in views {
        let path = out.join(format!("{stem}_{name}.mp4"));
        writers.push((VideoWriter::create(&path, spec)?, path));
    }
    let pb = crate::progress::bar(steps as u64, "video", global.quiet);
    let mut next_frame = 0.0;
    for step in 0..=steps {
        let t = step as f64 * timestep;
        if t + 1e-12 >= next_frame {
            for ((writer, _), (_, view)) in writers.iter_mut().zip(views) {
                writer.write_frame(&renderer.render(data, *view)?.rgb)?;
            }
            next_frame += 1.0 / f64::from(args.fps);
        }
        if step < steps {
            data.step();
        }
        pb.inc(1);
    }
    pb.finish_and_clear();
    for (writer, path) in writers {
        let frames = writer.finish()?;
        outln!(
            "{} ({frames} frames, {} fps, H.264)",
            path.display(),
            args.fps
        );
    }
    Ok(ExitStatus::Success)
}

/// Tiles frames of equal size into a grid (at most 4 per row) with a thin border.
pub fn contact_sheet(frames: &[Frame], path: &PathBuf) -> anyhow::Result<()> {
    let tiles = frames
        .iter()
        .map(|f| image::RgbImage::from_raw(f.width, f.height, f.rgb.clone()).context("frame size"))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let layout = dexjoco_sim::SheetLayout {
        columns: frames.len().min(4) as u32,
        tile: None,
        gap: 4,
        background: [255, 255, 255],
    };
    let sheet = dexjoco_sim::contact_sheet(&tiles, layout).context("no frames to tile")?;
    sheet
        .save(path)
        .with_context(|| format!("cannot write '{}'", path.display()))?;
    Ok(())
}

/// The task specs: the built-in ones, with those in `--tasks-dir` replacing or adding.
fn task_specs(args: &RenderArgs) -> anyhow::Result<Vec<TaskSpec>> {
    let dir = args.tasks_dir.as_deref();
    Ok(TaskSet::with_dir(dir)
        .with_context(|| match dir {
            Some(d) => format!("cannot read the task specs in '{}'", d.display()),
            None => "the built-in task specs".into(),
        })?
        .iter()
        .cloned()
        .collect())
}

fn render_settings(args: &RenderArgs) -> RenderSettings {
    RenderSettings {
        width: args.width.unwrap_or(args.size),
        height: args.height.unwrap_or(args.size),
        quality: RenderQuality::from_name(args.quality.name())
            .expect("every QualityArg is a preset"),
        depth: args.depth,
        geometry: args.geometry.geometry(),
    }
}

/// Renders a task's scene at its reset state from the named cameras.
fn render_task_scene(
    source: &SceneSource,
    spec: &TaskSpec,
    cameras: &[String],
    settings: RenderSettings,
) -> anyhow::Result<Vec<Frame>> {
    let scene = load_task_scene(source, spec)?;
    let mut env = TaskEnv::new(&scene, spec, EnvOptions::default())?;
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

/// `render --task T|all`.
fn run_task(global: &GlobalArgs, args: &RenderArgs, task: &str) -> anyhow::Result<ExitStatus> {
    let specs = task_specs(args)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| global.work_dir.join("render"));
    fs_err::create_dir_all(&out)?;
    let settings = render_settings(args);
    if task != "all" {
        let Some(spec) = specs.iter().find(|s| s.id == task) else {
            let ids: Vec<_> = specs.iter().map(|s| s.id.as_str()).collect();
            return Err(crate::settings::usage(
                format!("unknown task '{task}'"),
                format!("known tasks: {}, or all", ids.join(", ")),
            ));
        };
        let source = SceneSource::from_option(args.scene_dir.clone());
        let cameras: Vec<String> = if args.cameras.is_empty() {
            spec.cameras.iter().map(|c| c.camera.clone()).collect()
        } else {
            args.cameras.clone()
        };
        let frames = render_task_scene(&source, spec, &cameras, settings)?;
        let kind = if args.scene_dir.is_some() {
            "scene_dir"
        } else {
            "builtin"
        };
        for (c, f) in cameras.iter().zip(&frames) {
            let png = out.join(format!("{task}_{kind}_{c}.png"));
            f.save_png(&png)?;
            outln!("{}", png.display());
        }
        if frames.len() > 1 {
            let sheet = out.join(format!("{task}_{kind}_contact_sheet.png"));
            contact_sheet(&frames, &sheet)?;
            outln!("{}", sheet.display());
        }
        return Ok(ExitStatus::Success);
    }

    // Every task: built-in next to reference, same camera.
    let reference = args.scene_dir.clone().or_else(super::reference_scene_dir);
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
    let pb = crate::progress::bar(specs.len() as u64, "render", global.quiet);
    for spec in &specs {
        let camera = args
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
            match render_task_scene(&source, spec, &cams, settings) {
                Ok(mut f) => {
                    let frame = f.remove(0);
                    let png = out.join(format!("{}_{kind}_{camera}.png", spec.id));
                    frame.save_png(&png)?;
                    pair.push(frame);
                }
                Err(e) => {
                    tracing::debug!("{} ({kind}): {e:#}", spec.id);
                    failures.push(format!("{} ({kind} scene): {e:#}", spec.id));
                    pair.push(failed_tile());
                }
            }
        }
        tiles.extend(pair);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let sheet = out.join("tasks_contact_sheet.png");
    contact_sheet(&tiles, &sheet)?;
    outln!("{}", sheet.display());
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
