//! Render smoke test: real MuJoCo, real EGL (Mesa llvmpipe on CPU machines). Two cameras
//! each face an object of known colour at a known distance.

use std::path::PathBuf;

use dexjoco_render::{CameraView, Frame, RenderQuality, RenderSettings, Renderer};
use dexjoco_sim::Scene;
use dexjoco_sim::mujoco_rs::prelude::MjData;

fn probe() -> Scene {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/render_probe.xml");
    Scene::load(path).expect("probe scene loads")
}

fn settings(quality: RenderQuality) -> RenderSettings {
    RenderSettings {
        width: 160,
        height: 120,
        quality,
        depth: true,
        geometry: dexjoco_render::Geometry::Full,
    }
}

fn centre(f: &Frame) -> ([u8; 3], f32) {
    let (x, y) = (f.width / 2, f.height / 2);
    (f.pixel(x, y), f.depth_at(x, y).expect("depth rendered"))
}

#[test]
fn two_cameras_see_known_colours_at_known_depths() {
    let scene = probe();
    let top = scene.camera_id("top").unwrap();
    let side = scene.camera_id("side").unwrap();
    let mut data = MjData::new(&*scene.model);
    data.forward();
    // Zero gravity: stepping must leave the scene where it is.
    for _ in 0..50 {
        data.step();
    }
    let mut r = Renderer::new(&scene.model, settings(RenderQuality::FAST)).unwrap();

    let f = r.render(&mut data, CameraView::Fixed(top)).unwrap();
    assert_eq!((f.width, f.height, f.rgb.len()), (160, 120, 160 * 120 * 3));
    let (rgb, depth) = centre(&f);
    assert!(
        rgb[0] > 150 && rgb[1] < 60 && rgb[2] < 60,
        "top camera centre should be red, got {rgb:?}"
    );
    assert!(
        (depth - 1.3).abs() < 2e-3,
        "top camera centre depth {depth} m, expected 1.3 m"
    );
    // A corner of the image looks past the box into empty space: black, and far away.
    assert_eq!(f.pixel(0, 0), [0, 0, 0]);
    assert!(f.depth_at(0, 0).unwrap() > 50.0);

    let f = r.render(&mut data, CameraView::Fixed(side)).unwrap();
    let (rgb, depth) = centre(&f);
    assert!(
        rgb[1] > 150 && rgb[0] < 60 && rgb[2] < 60,
        "side camera centre should be green, got {rgb:?}"
    );
    assert!(
        (depth - 2.75).abs() < 2e-3,
        "side camera centre depth {depth} m, expected 2.75 m"
    );
}

#[test]
fn image_rows_are_top_down() {
    // The side camera looks along -x with +z up: the green box (z 0.25..0.75) is centred
    // at the camera's height and the blue ball (z 0.9..1.0) is above it, so its rows
    // must come first in a top-down image.
    let scene = probe();
    let side = scene.camera_id("side").unwrap();
    let mut data = MjData::new(&*scene.model);
    data.forward();
    let mut r = Renderer::new(&scene.model, settings(RenderQuality::FAST)).unwrap();
    let f = r.render(&mut data, CameraView::Fixed(side)).unwrap();
    let green_rows: Vec<u32> = (0..f.height)
        .filter(|&y| (0..f.width).any(|x| f.pixel(x, y)[1] > 150 && f.pixel(x, y)[0] < 60))
        .collect();
    let mid = f.height / 2;
    assert!(green_rows.contains(&mid));
    // The box spans +-0.25 m at 2.75 m with fovy 30: about 43% of the height, centred.
    let span = green_rows.len() as f32 / f.height as f32;
    let expected = (0.25f32 / 2.75) / (15f32.to_radians().tan());
    assert!(
        (span - expected).abs() < 0.03,
        "green spans {span} of the height, expected {expected}"
    );
    let first = *green_rows.first().unwrap();
    let last = *green_rows.last().unwrap();
    assert!(
        (first as i32 + last as i32 - f.height as i32 + 1).abs() <= 2,
        "box is not centred: rows {first}..{last}"
    );
    let blue_rows: Vec<u32> = (0..f.height)
        .filter(|&y| (0..f.width).any(|x| f.pixel(x, y)[2] > 150 && f.pixel(x, y)[0] < 60))
        .collect();
    assert!(!blue_rows.is_empty(), "the blue ball is not visible");
    assert!(
        blue_rows.iter().all(|&y| y < first),
        "blue rows {blue_rows:?} are not above the green box (from row {first})"
    );
}

/// Pixels along the red box's slanted edges that are neither background nor face colour.
fn blended_edge_pixels(f: &Frame) -> usize {
    let face = centre(f).0[0] as i32;
    f.rgb
        .chunks_exact(3)
        .filter(|p| p[1] < 30 && (p[0] as i32) > 25 && (p[0] as i32) < face - 25)
        .count()
}

#[test]
fn multisampling_blends_edges_only_when_on() {
    let scene = probe();
    let top = scene.camera_id("top").unwrap();
    let mut data = MjData::new(&*scene.model);
    data.forward();
    let mut aliased = Renderer::new(&scene.model, settings(RenderQuality::FAST)).unwrap();
    let fa = aliased.render(&mut data, CameraView::Fixed(top)).unwrap();
    let mut smooth = Renderer::new(
        &scene.model,
        settings(RenderQuality {
            samples: 8,
            ..RenderQuality::FAST
        }),
    )
    .unwrap();
    let fs = smooth.render(&mut data, CameraView::Fixed(top)).unwrap();
    let (a, s) = (blended_edge_pixels(&fa), blended_edge_pixels(&fs));
    assert!(
        s > 4 * a.max(5),
        "8x multisampling should blend many edge pixels: {s} vs {a} without"
    );
}

#[test]
fn orbit_camera_looks_at_its_target() {
    let scene = probe();
    let mut data = MjData::new(&*scene.model);
    data.forward();
    let mut r = Renderer::new(&scene.model, settings(RenderQuality::FAST)).unwrap();
    // Straight down onto the red box from 1.5 m above its top face.
    let view = CameraView::Orbit {
        lookat: [0.0, 2.0, 0.7],
        distance: 1.5,
        azimuth: 0.0,
        elevation: -90.0,
    };
    let f = r.render(&mut data, view).unwrap();
    let (rgb, depth) = centre(&f);
    assert!(
        rgb[0] > 150 && rgb[1] < 60,
        "orbit view centre should be red, got {rgb:?}"
    );
    assert!((depth - 1.5).abs() < 2e-3, "orbit depth {depth}");
}

#[test]
fn unknown_camera_lists_the_available_ones() {
    let err = probe().camera_id("nope").unwrap_err().to_string();
    assert!(
        err.contains("'nope'") && err.contains("top") && err.contains("side"),
        "{err}"
    );
}

#[test]
fn missing_asset_is_named() {
    let dir = std::env::temp_dir().join(format!("dexjoco-missing-asset-{}", std::process::id()));
    fs_err::create_dir_all(&dir).unwrap();
    let xml = dir.join("scene.xml");
    fs_err::write(
        &xml,
        r#"<mujoco><asset><mesh name="m" file="no_such_mesh.stl"/></asset>
           <worldbody><geom type="mesh" mesh="m"/></worldbody></mujoco>"#,
    )
    .unwrap();
    let err = Scene::load(&xml).unwrap_err().to_string();
    fs_err::remove_dir_all(&dir).ok();
    assert!(err.contains("no_such_mesh.stl"), "{err}");
    assert!(err.contains("scene.xml"), "{err}");
}

#[test]
fn reference_plant_scene_renders_from_its_front_camera() {
    let xml = dexjoco_testkit::upstream_dir().join("xmls/arena_arm_hand_plant.xml");
    let scene = Scene::load(&xml).expect("reference plant scene loads");
    let front = scene.camera_id("front").unwrap();
    let mut data = MjData::new(&*scene.model);
    data.forward();
    let mut r = Renderer::new(
        &scene.model,
        RenderSettings {
            width: 96,
            height: 96,
            ..RenderSettings::default()
        },
    )
    .unwrap();
    let f = r.render(&mut data, CameraView::Fixed(front)).unwrap();
    // Not a blank image: the table, robot and plant give many distinct colours.
    let mut colours: Vec<[u8; 3]> = f.rgb.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(
        colours.len() > 200,
        "only {} distinct colours",
        colours.len()
    );
}
