//! Augment's table looks are what MuJoCo itself draws when the model's `geom_matid` is
//! set (as the DexJoCo reference randomizes the table): the abstract scene's table geom
//! gets the material's texture, colour and lighting fields, compared field by field with
//! `mjv_updateScene` on a model copy so edited, for every look of a reference scene and of
//! a built-in one, and for a plain colour.

#[path = "../../sim/tests/common/mod.rs"]
mod common;

use dexjoco_render::randomize::{GeomLook, TABLE_GEOM, TableLibrary};
use dexjoco_sim::mujoco_rs::prelude::{
    MjData, MjModel, MjvCamera, MjvOption, MjvPerturb, MjvScene,
};
use dexjoco_sim::mujoco_rs::wrappers::mj_visualization::MjvGeom;

/// The table geom's material fields in the abstract scene MuJoCo builds for `model`.
fn drawn_table(model: &MjModel, table: usize) -> GeomLook {
    let mut data = MjData::new(model);
    data.forward();
    let mut scene = MjvScene::new(model, 20_000);
    let mut cam = MjvCamera::new_free(model);
    scene.update(
        &mut data,
        &MjvOption::default(),
        &MjvPerturb::default(),
        &mut cam,
    );
    let geom_type = dexjoco_sim::mujoco_rs::prelude::MjtObjBase::mjOBJ_GEOM as i32;
    fields(
        scene
            .geoms()
            .iter()
            .find(|g| g.objtype == geom_type && g.objid == table as i32)
            .expect("the table is drawn"),
    )
}

fn with_table(model: &MjModel, table: usize, matid: i32, rgba: [f32; 4]) -> MjModel {
    let mut m = model.clone();
    // SAFETY: `table` < ngeom; plain data of a model copy this test owns.
    unsafe {
        let f = m.ffi_mut();
        *f.geom_matid.add(table) = matid;
        for (i, c) in rgba.iter().enumerate() {
            *f.geom_rgba.add(4 * table + i) = *c;
        }
    }
    m
}

fn fields(g: &MjvGeom) -> GeomLook {
    GeomLook {
        matid: g.matid,
        texid: g.texid,
        texuniform: g.texuniform,
        texrepeat: g.texrepeat,
        rgba: g.rgba,
        emission: g.emission,
        specular: g.specular,
        shininess: g.shininess,
        reflectance: g.reflectance,
    }
}

fn check(model: &MjModel) {
    let library = TableLibrary::of_model(model, TABLE_GEOM).unwrap();
    let table = library.geom;
    let original_rgba = model.geom_rgba()[table];
    let mut textures = std::collections::BTreeSet::new();
    for look in &library.entries {
        let m = look.material.expect("the scene has table_ materials") as i32;
        let drawn = drawn_table(&with_table(model, table, m, original_rgba), table);
        assert_eq!(Some(drawn), look.geom, "{}", look.name);
        textures.insert(drawn.texid);
    }
    assert!(
        textures.len() > 5,
        "the looks have textures of their own: {textures:?}"
    );
    let colour = [0.3, 0.5, 0.7, 1.0];
    let drawn = drawn_table(&with_table(model, table, -1, colour), table);
    assert_eq!(drawn, GeomLook::of_colour(colour));
}

#[test]
fn table_looks_match_mujocos_own_material_fields() {
    check(&common::scene("hammer_nail").model);
    let spec = common::spec("click_mouse");
    check(&dexjoco_sim::builtin::load_builtin(&spec).unwrap().model);
}
