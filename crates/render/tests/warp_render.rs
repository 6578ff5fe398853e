//! The Warp batch renderer against MuJoCo's OpenGL renderer, on real scenes: the same
//! states, views and randomized looks rendered by both (Warp on its CPU device here), the
//! images alike within measured bounds; bytes independent of the batch size; the worker's
//! refusals clear. Needs the Python of `scripts/setup.sh --warp` (`$DEXJOCO_WARP_PYTHON`).

#[path = "../../sim/tests/common/mod.rs"]
mod common;

use dexjoco_render::compare::compare;
use dexjoco_render::randomize::{
    TABLE_GEOM, TableLibrary, VisualSample, apply_visuals, builtin_pool, warp_world,
};
use dexjoco_render::warp::{
    SceneXml, WarpBatch, WarpOptions, WarpRenderer, WarpWorker, view_slots,
};
use dexjoco_render::{Frame, RenderQuality, RenderSettings, Renderer};
use dexjoco_sim::Scene;
use dexjoco_sim::mujoco_rs::prelude::MjData;

fn worker() -> WarpWorker {
    WarpWorker::start(&WarpOptions {
        python: Some(dexjoco_testkit::warp_python()),
        device: "cpu".into(),
        worlds: None,
        supersample: None,
    })
    .expect("the Warp worker starts")
}

fn settings() -> RenderSettings {
    RenderSettings {
        width: 96,
        height: 96,
        quality: RenderQuality::FAST,
        depth: true,
        geometry: dexjoco_render::Geometry::Full,
    }
}

struct Case {
    scene: Scene,
    xml: SceneXml,
    table: TableLibrary,
}

fn builtin(task: &str) -> Case {
    let spec = common::spec(task);
    let xml = dexjoco_sim::builtin::scene_xml(&spec).unwrap();
    let scene = dexjoco_sim::builtin::load_builtin(&spec).unwrap();
    let table = TableLibrary::of_model(&scene.model, TABLE_GEOM).unwrap();
    Case {
        scene,
        xml: SceneXml::Text(xml),
        table,
    }
}

/// Both renderers' images of `n` randomized views of the scene's initial state.
fn both(case: &Case, n: usize, worlds: usize) -> (Vec<Frame>, Vec<Frame>) {
    let model = &case.scene.model;
    let mut data = MjData::new(&**model);
    data.forward();
    let pool = builtin_pool(dexjoco_core::ArmSetup::SingleArm);
    let nlight = model.ffi().nlight as usize;
    let samples: Vec<VisualSample> = (0..n)
        .map(|i| VisualSample::sample(i as u64 + 7, &pool, &case.table, nlight))
        .collect();
    let mut gl = Renderer::new(
        model,
        RenderSettings {
            depth: false,
            ..settings()
        },
    )
    .unwrap();
    let gl_frames = samples
        .iter()
        .map(|s| {
            gl.update_scene(&mut data, s.camera.view());
            apply_visuals(&mut gl, s, &case.table);
            gl.draw().unwrap()
        })
        .collect();
    let slots = view_slots(model, samples.iter().map(|s| s.camera.view()));
    let mut warp = WarpRenderer::open(
        worker(),
        &case.xml,
        model,
        settings(),
        worlds,
        case.table.geom,
        &slots,
    )
    .unwrap();
    let mut out = Vec::new();
    for chunk in samples.chunks(worlds) {
        let mut batch = WarpBatch::new(0);
        let f = batch.push_frame(&data);
        for s in chunk {
            batch.push_world(f, warp_world(model, &data, s.camera.view(), s, &case.table));
        }
        out.extend(warp.render(&batch).unwrap());
    }
    (gl_frames, out)
}

#[test]
fn warp_images_match_opengl_ones_and_do_not_depend_on_the_batch_size() {
    let case = builtin("hammer_nail");
    let (gl, warp) = both(&case, 6, 4);
    let mut psnr = Vec::new();
    for (i, (a, b)) in gl.iter().zip(&warp).enumerate() {
        let f = compare(a, b);
        eprintln!("view {i}: {f:?}");
        // Measured on this scene: PSNR 22.6-33.0 dB, SSIM 0.82-0.94 (docs/performance.md);
        // a wrong pose, light or table look costs far more.
        assert!(f.psnr > 19.0 && f.ssim > 0.75, "view {i}: {f:?}");
        psnr.push(f.psnr);
        let depth = b.depth.as_ref().expect("depth asked for");
        assert!(depth.iter().any(|d| d.is_finite() && *d > 0.3 && *d < 5.0));
    }
    let mean = psnr.iter().sum::<f64>() / psnr.len() as f64;
    assert!(mean > 23.0, "mean PSNR {mean}");
    let (_, again) = both(&case, 6, 5);
    assert!(warp == again, "batch size changed the bytes");
}

#[test]
fn a_world_that_differs_from_the_opened_scene_is_refused_by_name() {
    let case = builtin("hammer_nail");
    let model = &case.scene.model;
    let mut data = MjData::new(&**model);
    data.forward();
    let mut warp = WarpRenderer::open(
        worker(),
        &case.xml,
        model,
        settings(),
        2,
        case.table.geom,
        &[45.0],
    )
    .unwrap();
    let mut batch = WarpBatch::new(0);
    let f = batch.push_frame(&data);
    // A field of view no slot was opened for.
    let view = dexjoco_render::CameraView::Orbit {
        lookat: [0.0, 0.0, 1.0],
        distance: 1.4,
        azimuth: 30.0,
        elevation: -30.0,
    };
    let mut world = dexjoco_render::warp::WorldView::of(model, &data, view, case.table.geom);
    world.fovy = 60.0;
    batch.push_world(f, world);
    let e = warp.render(&batch).unwrap_err().to_string();
    assert!(e.contains("field of view 60"), "{e}");
    // More images than the renderer was opened for.
    let mut big = WarpBatch::new(0);
    let f = big.push_frame(&data);
    for _ in 0..3 {
        big.push_world(
            f,
            dexjoco_render::warp::WorldView::of(model, &data, view, case.table.geom),
        );
    }
    let e = warp.render(&big).unwrap_err().to_string();
    assert!(e.contains("3 images") && e.contains("opened for 2"), "{e}");
    // A Python without MuJoCo Warp: named, with what to do.
    let e = WarpWorker::start(&WarpOptions {
        python: Some("/usr/bin/true".into()),
        ..WarpOptions::default()
    })
    .err()
    .expect("refused")
    .to_string();
    assert!(
        e.contains("/usr/bin/true") && e.contains("setup.sh --warp"),
        "{e}"
    );
}
