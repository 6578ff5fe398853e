//! Visual randomization (augment's replays, eval's `--rand-full` episodes): third-person
//! camera from a pose pool, lights and headlight, table material; sampled from a seed of
//! its own and applied to the abstract scene per render (the model is never edited, so
//! physics is untouched).

use std::path::Path;

use dexjoco_core::ArmSetup;
use mujoco_rs::prelude::{MjModel, MjtObjBase};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::error::RenderError;
use crate::render::{CameraView, Renderer};
use crate::warp::WorldView;
use dexjoco_sim::SceneSource;
use mujoco_rs::prelude::MjData;
use mujoco_rs::wrappers::mj_model::traits::ModelType;

/// The table-top geom whose look randomization changes.
pub const TABLE_GEOM: &str = "table_visual";

/// Point every pool camera looks at (world frame, metres).
pub const LOOKAT: [f64; 3] = [0.0, 0.0, 1.0];
/// Light position offset range in x and y (metres): U(-0.3, 0.3).
pub const LIGHT_POS_RANGE: f64 = 0.3;
/// Light direction offset range in x and y: U(-0.4, 0.4).
pub const LIGHT_DIR_RANGE: f64 = 0.4;
/// Light diffuse colour range per channel.
pub const LIGHT_DIFFUSE: (f64, f64) = (0.3, 0.8);
/// Headlight ambient colour range per channel.
pub const HEADLIGHT_AMBIENT: (f64, f64) = (0.3, 0.7);
/// Headlight diffuse colour range per channel.
pub const HEADLIGHT_DIFFUSE: (f64, f64) = (0.2, 0.6);

/// The seed of one replay: the first 8 bytes of SHA-256 over (global seed, episode id,
/// replay index), so a replay's randomization never depends on which others run.
pub fn replay_seed(global: u64, episode: &str, replay: usize) -> u64 {
    let mut h = Sha256::new();
    h.update(b"dexjoco-augment/v1");
    h.update(global.to_le_bytes());
    h.update((episode.len() as u64).to_le_bytes());
    h.update(episode.as_bytes());
    h.update((replay as u64).to_le_bytes());
    let d = h.finalize();
    u64::from_le_bytes(d[..8].try_into().expect("8 bytes"))
}

/// One third-person camera pose: as the DexJoCo pools give it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraPose {
    /// Azimuth, degrees.
    pub azimuth: f64,
    /// Elevation, degrees (negative = above the look-at point).
    pub elevation: f64,
    /// Distance from the look-at point, metres.
    pub distance: f64,
}

impl CameraPose {
    /// The camera position: (0, 0, 1) + (-d cosE cosA, d cosE sinA, d sinE), E = -elevation.
    pub fn position(&self) -> [f64; 3] {
        let (a, e) = (self.azimuth.to_radians(), (-self.elevation).to_radians());
        let d = self.distance;
        [
            LOOKAT[0] - d * e.cos() * a.cos(),
            LOOKAT[1] + d * e.cos() * a.sin(),
            LOOKAT[2] + d * e.sin(),
        ]
    }

    /// The MuJoCo orbit camera with that position, looking at (0, 0, 1) (MuJoCo's
    /// azimuth turns the other way round, hence the sign).
    pub fn view(&self) -> CameraView {
        CameraView::Orbit {
            lookat: LOOKAT,
            distance: self.distance,
            azimuth: -self.azimuth,
            elevation: self.elevation,
        }
    }
}

/// A pool of third-person camera poses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraPool {
    /// Where it came from (a file, or `built-in single-arm` / `built-in bimanual`).
    pub source: String,
    /// The poses.
    pub poses: Vec<CameraPose>,
}

impl CameraPool {
    /// Reads a pool file: JSON `{"rows": [[azimuth, elevation, distance, ...], ...]}` as
    /// `replay_cameras.json` of the DexJoCo reference. A rejection names the file and
    /// the field (`rows[3][2]`).
    pub fn load(path: &Path) -> Result<Self, RenderError> {
        let bytes = fs_err::read(path).map_err(|e| RenderError::Pool {
            path: path.into(),
            message: e.to_string(),
        })?;
        let bad = |field: &str, what: String| RenderError::Pool {
            path: path.into(),
            message: format!("field '{field}': {what}"),
        };
        let doc: serde_json::Value = serde_json::from_slice(&bytes)
            .map_err(|e| bad("(document)", format!("not valid JSON: {e}")))?;
        let rows = doc
            .get("rows")
            .ok_or_else(|| {
                bad(
                    "rows",
                    "missing: expected {\"rows\": [[azimuth, elevation, distance, ...], ...]}"
                        .into(),
                )
            })?
            .as_array()
            .ok_or_else(|| bad("rows", "not an array of rows".into()))?;
        if rows.is_empty() {
            return Err(bad("rows", "no rows".into()));
        }
        let mut poses = Vec::with_capacity(rows.len());
        for (i, r) in rows.iter().enumerate() {
            let row = r.as_array().filter(|r| r.len() >= 3).ok_or_else(|| {
                bad(
                    &format!("rows[{i}]"),
                    format!("expected [azimuth, elevation, distance > 0, ...], found {r}"),
                )
            })?;
            let mut v = [0.0; 3];
            for (j, x) in row.iter().take(3).enumerate() {
                v[j] = x.as_f64().filter(|x| x.is_finite()).ok_or_else(|| {
                    bad(
                        &format!("rows[{i}][{j}]"),
                        format!("{x} is not a finite number"),
                    )
                })?;
            }
            if v[2] <= 0.0 {
                return Err(bad(
                    &format!("rows[{i}][2]"),
                    format!("distance {} is not positive", v[2]),
                ));
            }
            poses.push(CameraPose {
                azimuth: v[0],
                elevation: v[1],
                distance: v[2],
            });
        }
        Ok(Self {
            source: path.display().to_string(),
            poses,
        })
    }
}

impl CameraPool {
    /// The pool a task's random camera draws from: the file `explicit` when given, else
    /// beside a scene folder (`replay_cameras.json` for one arm, `replay_cameras_2.json`
    /// for two, in the folder or its parent, as the DexJoCo reference lays them out),
    /// else the built-in pool of the setup.
    pub fn for_task(
        explicit: Option<&Path>,
        scene: &SceneSource,
        setup: ArmSetup,
    ) -> Result<Self, RenderError> {
        if let Some(p) = explicit {
            return Self::load(p);
        }
        if let SceneSource::Dir(dir) = scene {
            let file = match setup {
                ArmSetup::SingleArm => "replay_cameras.json",
                ArmSetup::Bimanual => "replay_cameras_2.json",
            };
            for cand in [dir.join(file), dir.join("..").join(file)] {
                if cand.is_file() {
                    return Self::load(&cand);
                }
            }
        }
        Ok(builtin_pool(setup))
    }
}

/// The pool shipped for built-in scenes, laid out as the reference pools: single arm =
/// azimuth +-{30..70 step 10} x 5 elevations -4.10..-25.38 deg at 1.4 m; bimanual =
/// azimuth +-{30..60 step 7.5} x 5 elevations -30..-45.10 deg at 2.4 m.
pub fn builtin_pool(setup: ArmSetup) -> CameraPool {
    let (azimuths, elev, distance, name): (Vec<f64>, (f64, f64), f64, &str) = match setup {
        ArmSetup::SingleArm => (
            (0..5).map(|i| 30.0 + 10.0 * f64::from(i)).collect(),
            (-4.10, -25.38),
            1.4,
            "built-in single-arm",
        ),
        ArmSetup::Bimanual => (
            (0..5).map(|i| 30.0 + 7.5 * f64::from(i)).collect(),
            (-30.0, -45.10),
            2.4,
            "built-in bimanual",
        ),
    };
    let mut poses = Vec::with_capacity(50);
    for j in 0..5 {
        let elevation = elev.0 + (elev.1 - elev.0) * f64::from(j) / 4.0;
        for &a in &azimuths {
            for s in [-1.0, 1.0] {
                poses.push(CameraPose {
                    azimuth: s * a,
                    elevation,
                    distance,
                });
            }
        }
    }
    CameraPool {
        source: name.into(),
        poses,
    }
}

/// The table-top looks a replay picks from: the scene's `table_*` materials (the
/// reference texture library), or, for scenes without them, 20 procedural colours.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TableLibrary {
    /// The table-top geom id.
    pub geom: usize,
    /// Entries: a name and either a material id or an RGBA colour.
    pub entries: Vec<TableLook>,
}

/// One table-top look.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TableLook {
    /// Material name, or `procedural_NN`.
    pub name: String,
    /// Material id in the model, when the look is a material.
    pub material: Option<usize>,
    /// RGBA, when the look is a procedural colour.
    pub rgba: Option<[f32; 4]>,
    /// What the abstract scene's geom holds with this look: what `mjv_updateScene` copies
    /// from the material (its texture above all), as if the model's `geom_matid` were
    /// set, as the DexJoCo reference does.
    #[serde(default)]
    pub geom: Option<GeomLook>,
}

/// The material fields of an abstract-scene geom (`mjvGeom`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GeomLook {
    /// Material id (-1: none).
    pub matid: i32,
    /// Texture id (-1: none).
    pub texid: i32,
    /// The material's `texuniform`.
    pub texuniform: i32,
    /// The material's `texrepeat`.
    pub texrepeat: [f32; 2],
    /// Colour.
    pub rgba: [f32; 4],
    /// Emission.
    pub emission: f32,
    /// Specular.
    pub specular: f32,
    /// Shininess.
    pub shininess: f32,
    /// Reflectance.
    pub reflectance: f32,
}

impl GeomLook {
    /// What `mjv_updateScene` gives a geom of material `m` with no colour of its own.
    pub fn of_material(model: &MjModel, m: usize) -> Self {
        use mujoco_rs::mujoco_c::mjtTextureRole;
        Self {
            matid: m as i32,
            texid: model.mat_texid()[m][mjtTextureRole::mjTEXROLE_RGB as usize],
            texuniform: i32::from(model.mat_texuniform()[m]),
            texrepeat: model.mat_texrepeat()[m],
            rgba: model.mat_rgba()[m],
            emission: model.mat_emission()[m],
            specular: model.mat_specular()[m],
            shininess: model.mat_shininess()[m],
            reflectance: model.mat_reflectance()[m],
        }
    }

    /// What `mjv_updateScene` gives a geom of no material and colour `rgba`.
    pub fn of_colour(rgba: [f32; 4]) -> Self {
        Self {
            matid: -1,
            texid: -1,
            texuniform: 0,
            texrepeat: [0.0, 0.0],
            rgba,
            emission: 0.0,
            specular: 0.5,
            shininess: 0.5,
            reflectance: 0.0,
        }
    }

    /// Sets these fields of `g`.
    pub fn apply(&self, g: &mut mujoco_rs::wrappers::mj_visualization::MjvGeom) {
        g.matid = self.matid;
        g.texid = self.texid;
        g.texuniform = self.texuniform;
        g.texrepeat = self.texrepeat;
        g.rgba = self.rgba;
        g.emission = self.emission;
        g.specular = self.specular;
        g.shininess = self.shininess;
        g.reflectance = self.reflectance;
    }
}

/// Size of the procedural library.
pub const PROCEDURAL_LOOKS: usize = 20;

impl TableLibrary {
    /// The library of `model`'s table-top geom `geom_name`.
    pub fn of_model(model: &MjModel, geom_name: &str) -> Result<Self, RenderError> {
        let geom = dexjoco_sim::name_id(model, dexjoco_core::NameKind::Geom, geom_name)
            .ok_or_else(|| RenderError::SceneLacks {
                kind: "table-top geom",
                name: geom_name.into(),
            })?;
        let nmat = model.ffi().nmat as usize;
        let mut entries = Vec::new();
        for m in 0..nmat {
            if let Some(name) = material_name(model, m)
                && name.starts_with("table_")
            {
                entries.push(TableLook {
                    name,
                    material: Some(m),
                    rgba: None,
                    geom: Some(GeomLook::of_material(model, m)),
                });
            }
        }
        if entries.is_empty() {
            entries = (0..PROCEDURAL_LOOKS)
                .map(|i| TableLook {
                    name: format!("procedural_{i:02}"),
                    material: None,
                    rgba: Some(procedural_colour(i)),
                    geom: Some(GeomLook::of_colour(procedural_colour(i))),
                })
                .collect();
        }
        Ok(Self { geom, entries })
    }
}

fn material_name(model: &MjModel, id: usize) -> Option<String> {
    model
        .id_to_name(MjtObjBase::mjOBJ_MATERIAL, id)
        .map(str::to_owned)
}

/// Twenty distinct table colours: wood, plaster and metal tones spread over hue and
/// brightness (deterministic).
fn procedural_colour(i: usize) -> [f32; 4] {
    let h = (i as f32 * 0.618_034).fract();
    let v = 0.35 + 0.5 * ((i * 7 % 20) as f32 / 19.0);
    let s = 0.25 + 0.4 * ((i * 3 % 5) as f32 / 4.0);
    let k = |n: f32| {
        let k = (n + h * 6.0) % 6.0;
        v - v * s * k.min(4.0 - k).clamp(0.0, 1.0)
    };
    [k(5.0), k(3.0), k(1.0), 1.0]
}

/// The sampled offsets and colours of one scene light.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LightSample {
    /// Position offset in x, y (metres).
    pub pos_offset: [f64; 2],
    /// Direction offset in x, y.
    pub dir_offset: [f64; 2],
    /// Diffuse RGB.
    pub diffuse: [f64; 3],
}

/// Everything sampled for one replay.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VisualSample {
    /// The replay's seed.
    pub seed: u64,
    /// Index into the camera pool.
    pub camera_index: usize,
    /// The camera pose.
    pub camera: CameraPose,
    /// Index into the table library.
    pub table_index: usize,
    /// The table look's name.
    pub table: String,
    /// Headlight ambient RGB.
    pub headlight_ambient: [f64; 3],
    /// Headlight diffuse RGB.
    pub headlight_diffuse: [f64; 3],
    /// One sample per model light, in light id order.
    pub lights: Vec<LightSample>,
}

fn rgb(rng: &mut ChaCha8Rng, (lo, hi): (f64, f64)) -> [f64; 3] {
    [
        rng.random_range(lo..hi),
        rng.random_range(lo..hi),
        rng.random_range(lo..hi),
    ]
}

impl VisualSample {
    /// The views a replay renders: this sample's third-person view, then the fixed cameras.
    pub fn views<'a>(&self, fixed: &'a [usize]) -> impl Iterator<Item = CameraView> + 'a {
        std::iter::once(self.camera.view()).chain(fixed.iter().map(|i| CameraView::Fixed(*i)))
    }
    /// Samples a replay's randomization from its seed.
    pub fn sample(seed: u64, pool: &CameraPool, table: &TableLibrary, nlight: usize) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let camera_index = rng.random_range(0..pool.poses.len());
        let table_index = rng.random_range(0..table.entries.len());
        let headlight_ambient = rgb(&mut rng, HEADLIGHT_AMBIENT);
        let headlight_diffuse = rgb(&mut rng, HEADLIGHT_DIFFUSE);
        let (p, d) = (LIGHT_POS_RANGE, LIGHT_DIR_RANGE);
        let lights = (0..nlight)
            .map(|_| LightSample {
                pos_offset: [rng.random_range(-p..p), rng.random_range(-p..p)],
                dir_offset: [rng.random_range(-d..d), rng.random_range(-d..d)],
                diffuse: rgb(&mut rng, LIGHT_DIFFUSE),
            })
            .collect();
        Self {
            seed,
            camera_index,
            camera: pool.poses[camera_index],
            table_index,
            table: table.entries[table_index].name.clone(),
            headlight_ambient,
            headlight_diffuse,
            lights,
        }
    }
}

/// Applies a sample to the renderer's abstract scene, after `update_scene` and before
/// `draw`: the scene's lights are rebuilt from the model on every update, so each render
/// starts from the original lights ("reset to the scene's original, then offset").
pub fn apply_visuals(renderer: &mut Renderer, sample: &VisualSample, table: &TableLibrary) {
    let f = |v: f64| v as f32;
    for light in renderer.scene_mut().lights_mut() {
        if light.headlight != 0 {
            light.ambient = sample.headlight_ambient.map(f);
            light.diffuse = sample.headlight_diffuse.map(f);
        } else if let Some(s) = usize::try_from(light.id)
            .ok()
            .and_then(|i| sample.lights.get(i))
        {
            light.pos[0] += f(s.pos_offset[0]);
            light.pos[1] += f(s.pos_offset[1]);
            light.dir[0] += f(s.dir_offset[0]);
            light.dir[1] += f(s.dir_offset[1]);
            light.diffuse = s.diffuse.map(f);
        }
    }
    let look = &table.entries[sample.table_index];
    let table_geom = table.geom as i32;
    let geom_type = MjtObjBase::mjOBJ_GEOM as i32;
    for g in renderer.scene_geoms_mut() {
        if g.objtype == geom_type && g.objid == table_geom {
            match (look.geom, look.material, look.rgba) {
                (Some(l), _, _) => l.apply(g),
                // Libraries made before the looks were recorded: what they did.
                (None, Some(m), _) => {
                    g.matid = m as i32;
                    g.rgba = [1.0, 1.0, 1.0, 1.0];
                }
                (None, None, Some(c)) => {
                    g.matid = -1;
                    g.rgba = c;
                }
                (None, None, None) => {}
            }
        }
    }
}

/// The world a sample makes for the Warp renderer: what [`apply_visuals`] does to the
/// OpenGL scene (lights offset and recoloured, headlight recoloured, the table's look),
/// as one world's values.
pub fn warp_world<M: ModelType>(
    model: &MjModel,
    data: &MjData<M>,
    view: CameraView,
    sample: &VisualSample,
    table: &TableLibrary,
) -> WorldView {
    let mut world = WorldView::of(model, data, view, table.geom);
    world.head_ambient = sample.headlight_ambient;
    world.head_diffuse = sample.headlight_diffuse;
    for (light, s) in world.lights.iter_mut().zip(&sample.lights) {
        light.pos[0] += s.pos_offset[0];
        light.pos[1] += s.pos_offset[1];
        light.dir[0] += s.dir_offset[0];
        light.dir[1] += s.dir_offset[1];
        // OpenGL lights along the unit direction; the ray tracer along the vector given.
        let norm = light.dir.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm > 0.0 {
            light.dir = light.dir.map(|v| v / norm);
        }
        light.diffuse = s.diffuse;
    }
    let look = &table.entries[sample.table_index];
    if let Some(m) = look.material {
        world.table_matid = m as i32;
        world.table_rgba = [1.0, 1.0, 1.0, 1.0];
    } else if let Some(c) = look.rgba {
        world.table_matid = -1;
        world.table_rgba = c;
    }
    world
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_differ_per_replay_and_episode_and_are_stable() {
        let a = replay_seed(0, "click_mouse/episode_000000", 0);
        assert_eq!(a, replay_seed(0, "click_mouse/episode_000000", 0));
        assert_ne!(a, replay_seed(0, "click_mouse/episode_000000", 1));
        assert_ne!(a, replay_seed(0, "click_mouse/episode_000001", 0));
        assert_ne!(a, replay_seed(1, "click_mouse/episode_000000", 0));
    }

    #[test]
    fn builtin_pools_have_50_poses_matching_the_reference_layout() {
        for setup in [ArmSetup::SingleArm, ArmSetup::Bimanual] {
            let p = builtin_pool(setup);
            assert_eq!(p.poses.len(), 50);
        }
        let p = builtin_pool(ArmSetup::SingleArm);
        let pos = p.poses[0].position();
        let d = ((pos[0] - LOOKAT[0]).powi(2)
            + (pos[1] - LOOKAT[1]).powi(2)
            + (pos[2] - LOOKAT[2]).powi(2))
        .sqrt();
        assert!((d - 1.4).abs() < 1e-9);
        assert!(pos[2] > LOOKAT[2], "elevation negative = camera above");
    }

    #[test]
    fn procedural_colours_are_distinct() {
        let c: Vec<[f32; 4]> = (0..PROCEDURAL_LOOKS).map(procedural_colour).collect();
        for i in 0..c.len() {
            for j in i + 1..c.len() {
                assert_ne!(c[i], c[j], "{i} {j}");
            }
        }
    }

    #[test]
    fn sampled_values_stay_inside_the_specified_ranges_and_cover_them() {
        let pool = builtin_pool(ArmSetup::SingleArm);
        let table = TableLibrary {
            geom: 0,
            entries: (0..PROCEDURAL_LOOKS)
                .map(|i| TableLook {
                    name: format!("procedural_{i:02}"),
                    material: None,
                    rgba: Some(procedural_colour(i)),
                    geom: None,
                })
                .collect(),
        };
        let inside = |v: f64, (lo, hi): (f64, f64)| v >= lo && v < hi;
        let mut cams = std::collections::BTreeSet::new();
        let mut looks = std::collections::BTreeSet::new();
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for r in 0..2000 {
            let s = VisualSample::sample(replay_seed(3, "t/e", r), &pool, &table, 2);
            cams.insert(s.camera_index);
            looks.insert(s.table_index);
            assert_eq!(s.camera, pool.poses[s.camera_index]);
            for v in s.headlight_ambient {
                assert!(inside(v, HEADLIGHT_AMBIENT), "{v}");
            }
            for v in s.headlight_diffuse {
                assert!(inside(v, HEADLIGHT_DIFFUSE), "{v}");
            }
            assert_eq!(s.lights.len(), 2);
            for l in &s.lights {
                for v in l.pos_offset {
                    assert!(inside(v, (-LIGHT_POS_RANGE, LIGHT_POS_RANGE)), "{v}");
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
                for v in l.dir_offset {
                    assert!(inside(v, (-LIGHT_DIR_RANGE, LIGHT_DIR_RANGE)), "{v}");
                }
                for v in l.diffuse {
                    assert!(inside(v, LIGHT_DIFFUSE), "{v}");
                }
            }
        }
        // Uniform choice: every pose and every look is drawn; offsets span the range.
        assert_eq!(cams.len(), 50);
        assert_eq!(looks.len(), PROCEDURAL_LOOKS);
        assert!(lo < -0.29 && hi > 0.29, "{lo} {hi}");
    }

    #[test]
    fn the_reference_pool_loads_and_matches_its_layout() {
        let dir = dexjoco_testkit::upstream_dir();
        let p = CameraPool::load(&dir.join("replay_cameras.json")).unwrap();
        assert_eq!(p.poses.len(), 50);
        for c in &p.poses {
            assert!((c.distance - 1.4).abs() < 1e-5);
            assert!((30.0 - 1e-4..=70.0 + 1e-4).contains(&c.azimuth.abs()));
            assert!((-25.4..=-4.0).contains(&c.elevation), "{}", c.elevation);
        }
        let q = CameraPool::load(&dir.join("replay_cameras_2.json")).unwrap();
        assert!(q.poses.iter().all(|c| (c.distance - 2.4).abs() < 1e-5));
        let bad = std::env::temp_dir().join("dexjoco-sim-bad-pool.json");
        fs_err::write(&bad, r#"{"rows": [[1.0, 2.0]]}"#).unwrap();
        let e = CameraPool::load(&bad).unwrap_err().to_string();
        assert!(e.contains("rows[0]"), "{e}");
    }
}
