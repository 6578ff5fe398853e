//! One module per subcommand.

pub mod augment;
pub mod bench;
pub mod bench_augment;
pub mod cameras;
pub mod convert;
pub mod dataset;
pub mod doctor;
pub mod eval;
pub mod export;
pub mod generate;
pub mod ingest;
pub mod render;
pub mod scripted;
pub mod stats;

/// The built-in tabletop scene (also the default of `render` and `bench render`).
pub const TABLETOP_XML: &str = include_str!("../../crates/sim/assets/tabletop.xml");

/// The DexJoCo reference scenes' `xmls/`, when found (see [`crate::locate::reference_scenes`]).
pub fn reference_scene_dir() -> Option<std::path::PathBuf> {
    crate::locate::reference_scenes()
        .map(|l| l.path)
        .filter(|p| p.is_dir())
}

/// Loads a scene file, or the built-in tabletop scene when none is given.
pub fn load_scene(path: Option<&std::path::Path>) -> anyhow::Result<dexjoco_sim::Scene> {
    Ok(match path {
        Some(p) => dexjoco_sim::Scene::load(p)?,
        None => dexjoco_sim::Scene::from_xml_str(TABLETOP_XML, "<built-in tabletop>")?,
    })
}
