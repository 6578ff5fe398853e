//! The first-frames sheet of a run (`generate_sheet.png`): each kept episode's reset,
//! rendered from one view above the placement range, tiled, so that the spread of object poses is
//! seen at a glance. Rendering needs EGL (a GPU, or Mesa on a CPU); where there is none,
//! the run goes on without the sheet. The pixels depend on the renderer, so this is, with
//! the timing, one of the two files whose bytes depend on the machine.

use std::path::Path;

use dexjoco_core::TaskSpec;
use dexjoco_render::{
    CameraView, RenderQuality, RenderSettings, Renderer, SheetLayout, contact_sheet,
};
use dexjoco_sim::{EnvOptions, Scene, TaskEnv};

use crate::error::GenerateError;

/// The most episodes shown.
pub const SHEET_TILES: usize = 24;
/// Tile side in pixels.
const TILE: u32 = 160;

/// The view of every tile: from above, onto the middle of the first placed object's
/// placement range (at its height in the first reset), far enough to see the whole range
/// and the objects around it; `spec`'s first camera for a task without placement.
fn view(scene: &Scene, spec: &TaskSpec, first: &[f64]) -> Result<CameraView, GenerateError> {
    let layout = spec.state_layout();
    let placed = spec.placement.first().and_then(|p| {
        let f = layout.get(&format!("{}.pose", p.object))?;
        Some((p, first.get(f.start..f.start + 3)?.to_vec()))
    });
    let Some((p, at)) = placed else {
        let camera = spec
            .cameras
            .first()
            .ok_or_else(|| GenerateError::Spec(format!("task '{}' has no camera", spec.id)))?;
        return Ok(CameraView::Fixed(scene.camera_id(&camera.camera)?));
    };
    let mut lookat = [at[0], at[1], at[2]];
    for (k, axis) in p.axes.iter().enumerate() {
        lookat[axis.index()] = 0.5 * (p.low[k] + p.high[k]);
    }
    let span = ((p.high[0] - p.low[0]).powi(2) + (p.high[1] - p.low[1]).powi(2)).sqrt();
    Ok(CameraView::Orbit {
        lookat,
        distance: (0.9 + 2.0 * span).min(2.5),
        azimuth: 180.0,
        elevation: -60.0,
    })
}

/// Renders the resets `resets` (the first [`SHEET_TILES`]), all from one view above the
/// placement range, and writes the sheet as a PNG at `path`. Nothing is written when
/// there are none.
pub fn write_first_frames(
    path: &Path,
    scene: &Scene,
    spec: &TaskSpec,
    resets: &[&[f64]],
) -> Result<(), GenerateError> {
    let Some(first) = resets.first() else {
        return Ok(());
    };
    let view = view(scene, spec, first)?;
    let settings = RenderSettings {
        width: TILE,
        height: TILE,
        quality: RenderQuality::FAST,
        ..RenderSettings::default()
    };
    let mut renderer = Renderer::new(&scene.model, settings)?;
    let mut tiles = Vec::new();
    for reset in resets.iter().take(SHEET_TILES) {
        let mut env = TaskEnv::from_initial_state(scene, spec, reset, EnvOptions::default())?;
        let frame = renderer.render(env.data_mut(), view)?;
        let tile = image::RgbImage::from_raw(frame.width, frame.height, frame.rgb)
            .expect("a frame holds width x height RGB pixels");
        tiles.push(tile);
    }
    let layout = SheetLayout {
        columns: 6,
        tile: None,
        gap: 4,
        background: [255, 255, 255],
    };
    let Some(sheet) = contact_sheet(&tiles, layout) else {
        return Ok(());
    };
    let mut png = Vec::new();
    sheet
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .map_err(|e| GenerateError::Figure {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
    Ok(dexjoco_formats::write_atomic(path, &png)?)
}
