//! One module per subcommand.

pub mod augment;
pub mod bench;
pub mod bench_augment;
pub mod bench_convert;
pub mod cameras;
pub mod convert;
pub mod doctor;
pub mod export;
pub mod ingest;
pub mod render;
pub mod scripted;
pub mod stats;

/// The built-in tabletop scene (also the default of `render` and `bench render`).
pub const TABLETOP_XML: &str = include_str!("../../crates/sim/assets/tabletop.xml");

/// The DexJoCo reference scenes, when the shared folder is beside the checkout.
pub fn reference_scene_dir() -> Option<std::path::PathBuf> {
    let candidates = [
        std::env::var_os("DEXJOCO_UPSTREAM").map(std::path::PathBuf::from),
        Some(std::path::PathBuf::from("../shared/dexjoco-upstream")),
        Some(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/dexjoco-upstream")),
    ];
    candidates
        .into_iter()
        .flatten()
        .map(|p| p.join("xmls"))
        .find(|p| p.is_dir())
}

/// Loads a scene file, or the built-in tabletop scene when none is given.
pub fn load_scene(path: Option<&std::path::Path>) -> anyhow::Result<dexjoco_sim::Scene> {
    Ok(match path {
        Some(p) => dexjoco_sim::Scene::load(p)?,
        None => dexjoco_sim::Scene::from_xml_str(TABLETOP_XML, "<built-in tabletop>")?,
    })
}
