//! The output fingerprint (`augment_settings.json`) covers what decides the bytes beyond
//! the flags: every file a scene loads (an included robot or object file, a mesh, a
//! texture) and the versions of the programs. A resume after any of them changed is
//! refused, naming what changed, and `--overwrite` starts over.

use std::path::{Path, PathBuf};

use dexjoco_augment::{AugmentConfig, SETTINGS_FILE, augment};
use dexjoco_core::NoProgress;
use dexjoco_render::RenderSettings;
use dexjoco_sim::SceneSource;

/// The reference scenes as a folder of links, with `own` copied in so it can be edited.
fn scene_folder(dir: &Path, own: &str) -> PathBuf {
    let xmls = dexjoco_testkit::reference_scene_dir();
    let folder = dir.join("xmls");
    fs_err::create_dir_all(&folder).unwrap();
    for entry in fs_err::read_dir(&xmls).unwrap() {
        let entry = entry.unwrap();
        let to = folder.join(entry.file_name());
        if entry.file_name() == own {
            fs_err::copy(entry.path(), &to).unwrap();
        } else {
            std::os::unix::fs::symlink(entry.path(), &to).unwrap();
        }
    }
    folder
}

/// Physics only (no replay rendered): what writes and checks the fingerprint.
fn config(scenes: &Path, out: &Path) -> AugmentConfig {
    AugmentConfig {
        replays: 0,
        scene: SceneSource::Dir(scenes.to_path_buf()),
        settings: RenderSettings {
            width: 32,
            height: 32,
            ..RenderSettings::default()
        },
        max_frames: Some(4),
        contact_sheet: false,
        extend_steps: 0,
        ..AugmentConfig::new(
            vec![
                dexjoco_testkit::workspace_root().join("datasets/demos/click_mouse/episode_000000"),
            ],
            out,
        )
    }
}

#[test]
fn editing_an_included_scene_file_between_runs_is_refused_naming_it() {
    let tmp = tempfile::tempdir().unwrap();
    // The click_mouse scene includes its mouse from this file.
    let scenes = scene_folder(tmp.path(), "mouse_nolight.xml");
    let out = tmp.path().join("aug");
    let c = config(&scenes, &out);
    augment(&c, &NoProgress).unwrap();
    let settings = fs_err::read_to_string(out.join(SETTINGS_FILE)).unwrap();
    for file in [
        "mouse_nolight.xml",
        "panda_allegro_copy.xml",
        "table_arena/textures/ceramic.png",
    ] {
        assert!(
            settings.contains(&format!("\"{file}\"")),
            "{file}: {settings}"
        );
    }
    // The same scene: a resume.
    augment(&c, &NoProgress).unwrap();

    let included = scenes.join("mouse_nolight.xml");
    let mut xml = fs_err::read_to_string(&included).unwrap();
    xml.push_str("<!-- edited -->\n");
    fs_err::write(&included, xml).unwrap();
    let err = augment(&c, &NoProgress).unwrap_err().to_string();
    assert!(
        err.contains("tasks.click_mouse.scene_files.mouse_nolight.xml: \"sha256:")
            && err.contains("--overwrite"),
        "{err}"
    );
    // --overwrite starts over with the edited scene.
    let over = AugmentConfig {
        overwrite: true,
        ..c.clone()
    };
    augment(&over, &NoProgress).unwrap();
    augment(&c, &NoProgress).unwrap();
}

#[test]
fn an_output_made_by_another_version_is_refused_naming_it() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("aug");
    let c = AugmentConfig {
        scene: SceneSource::BuiltIn,
        ..config(tmp.path(), &out)
    };
    augment(&c, &NoProgress).unwrap();
    // As if another MuJoCo had made the folder.
    let path = out.join(SETTINGS_FILE);
    let mut settings: serde_json::Value =
        serde_json::from_slice(&fs_err::read(&path).unwrap()).unwrap();
    let mujoco = dexjoco_sim::mujoco_version();
    assert_eq!(settings["versions"]["mujoco"], mujoco.as_str());
    assert!(
        settings["versions"]["x264"]
            .as_str()
            .unwrap()
            .starts_with("x264 - core "),
        "{settings}"
    );
    settings["versions"]["mujoco"] = "3.1.0".into();
    fs_err::write(&path, serde_json::to_vec_pretty(&settings).unwrap()).unwrap();
    let err = augment(&c, &NoProgress).unwrap_err().to_string();
    assert!(
        err.contains(&format!("versions.mujoco: \"{mujoco}\" (was \"3.1.0\")"))
            && err.contains("--overwrite"),
        "{err}"
    );
}
