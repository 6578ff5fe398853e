//! The opt-in light geometry on the DexJoCo reference hammer_nail scene: far fewer
//! triangles drawn, an image close to the full render, the same physics (every replay's
//! states, records and success identical, only the videos differ), and the default output
//! untouched by the option's existence.

use std::path::{Path, PathBuf};

use dexjoco_augment::{AugmentConfig, augment, geometry_difference};
use dexjoco_core::NoProgress;
use dexjoco_render::{Geometry, RenderSettings};
use dexjoco_sim::SceneSource;

fn config(out: &Path, geometry: Geometry) -> AugmentConfig {
    AugmentConfig {
        replays: 2,
        seed: 3,
        scene: SceneSource::Dir(dexjoco_testkit::reference_scene_dir()),
        settings: RenderSettings {
            width: 96,
            height: 96,
            geometry,
            ..RenderSettings::default()
        },
        keep_failed: true,
        max_frames: Some(40),
        contact_sheet: false,
        extend_steps: 0,
        ..AugmentConfig::new(
            vec![
                dexjoco_testkit::workspace_root().join("datasets/demos/hammer_nail/episode_000000"),
            ],
            out,
        )
    }
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    dexjoco_testkit::file_tree(dir).into_iter().collect()
}

#[test]
fn light_geometry_draws_fewer_triangles_close_to_the_full_image_with_the_same_physics() {
    let tmp = tempfile::tempdir().unwrap();
    let d = geometry_difference(&config(&tmp.path().join("x"), Geometry::Light), 12).unwrap();
    assert!(
        d.triangles_light * 4 < d.triangles_full,
        "{} -> {} triangles",
        d.triangles_full,
        d.triangles_light
    );
    assert!(d.psnr_min > 28.0 && d.ssim_min > 0.97, "{d:?}");
    assert!(
        d.psnr_mean.is_finite(),
        "the light image is not the full one: {d:?}"
    );

    let (full, light): (PathBuf, PathBuf) = (tmp.path().join("full"), tmp.path().join("light"));
    augment(&config(&full, Geometry::Full), &NoProgress).unwrap();
    let report = augment(&config(&light, Geometry::Light), &NoProgress).unwrap();
    assert_eq!(report.replays.len(), 2);
    let (a, b) = (files(&full), files(&light));
    assert_eq!(
        a.iter().map(|(k, _)| k).collect::<Vec<_>>(),
        b.iter().map(|(k, _)| k).collect::<Vec<_>>()
    );
    let mut videos_differ = 0;
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        if name.ends_with(".png") {
            // The replay's first frame, as a preview.
        } else if name.ends_with(".mp4") {
            videos_differ += usize::from(x != y);
        } else if name == "augment_settings.json" || name.starts_with("augment_report") {
            // They name the geometry (the light one only).
            let (x, y) = (String::from_utf8_lossy(x), String::from_utf8_lossy(y));
            assert!(!x.contains("geometry"), "{name}: {x}");
            assert!(
                y.contains("\"geometry\": \"light\"") || y.contains("light geometry"),
                "{name}: {y}"
            );
        } else {
            assert!(x == y, "{name} differs: physics and records must not");
        }
    }
    assert_eq!(
        videos_differ, 2,
        "each replay's video is rendered with other meshes"
    );

    // A resume with the other geometry is refused, naming it.
    let err = augment(&config(&full, Geometry::Light), &NoProgress).unwrap_err();
    assert!(err.to_string().contains("geometry: \"light\""), "{err}");
}
