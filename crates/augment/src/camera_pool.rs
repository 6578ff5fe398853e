//! Building a third-person camera pose pool the way the DexJoCo paper did: sample poses
//! uniformly on a sphere around the workspace, score each by how much of the task's
//! objects it cannot see (ray casts from the camera to points on the objects), keep the
//! least occluded.
//!
//! Poses use the reference pools' convention ([`CameraPose`]): azimuth and elevation in
//! degrees (negative elevation = above the look-at point (0, 0, 1)), distance in metres.

use std::collections::BTreeSet;

use dexjoco_core::{ArmSetup, NameKind, PoseSource, TaskSpec};
use dexjoco_sim::mujoco_rs::prelude::{MjData, MjModel, MjtObjBase};
use dexjoco_sim::{EnvOptions, Scene, TaskEnv, name_id};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::error::AugmentError;
use dexjoco_render::randomize::{CameraPool, CameraPose};

/// Geom groups that count as visible (MuJoCo's default rendering shows groups 0-2).
const VISIBLE_GROUPS: [u8; 6] = [1, 1, 1, 0, 0, 0];

/// How to build a pool.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoolOptions {
    /// Poses kept.
    pub count: usize,
    /// Poses sampled and scored.
    pub candidates: usize,
    /// Distance from the look-at point, metres.
    pub distance: f64,
    /// Elevation band, degrees, as the pools write it (negative = above): (a, b) in any
    /// order.
    pub elevation: (f64, f64),
    /// Azimuth band, degrees: (a, b) in any order.
    pub azimuth: (f64, f64),
    /// Seed of the sampling.
    pub seed: u64,
}

impl PoolOptions {
    /// The reference pools' geometry for a setup: 1.4 m and elevations -2..-30 for one
    /// arm, 2.4 m and -25..-50 for two; azimuths within +-90 (the robot's side).
    pub fn for_setup(setup: ArmSetup) -> Self {
        let (distance, elevation) = match setup {
            ArmSetup::SingleArm => (1.4, (-2.0, -30.0)),
            ArmSetup::Bimanual => (2.4, (-25.0, -50.0)),
        };
        Self {
            count: 50,
            candidates: 2000,
            distance,
            elevation,
            azimuth: (-90.0, 90.0),
            seed: 0,
        }
    }
}

/// One scored pose.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ScoredPose {
    /// The pose.
    pub pose: CameraPose,
    /// Fraction of the target points hidden behind something else, 0..=1.
    pub occlusion: f64,
}

/// A built pool: the kept poses and every candidate with its score.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BuiltPool {
    /// Kept poses, sorted by (azimuth, elevation).
    pub kept: Vec<ScoredPose>,
    /// Every candidate, in sampling order.
    pub candidates: Vec<ScoredPose>,
    /// Target points the rays aim at.
    pub targets: usize,
    /// The bodies whose geoms give the target points.
    pub target_bodies: Vec<String>,
}

impl BuiltPool {
    /// The kept poses as a [`CameraPool`].
    pub fn pool(&self, source: &str) -> CameraPool {
        CameraPool {
            source: source.into(),
            poses: self.kept.iter().map(|s| s.pose).collect(),
        }
    }

    /// The pool file, in the reference format: `{"rows": [[azimuth, elevation, distance,
    /// 45], ...]}` (the fourth value is unused, as in `replay_cameras.json`).
    pub fn to_json(&self) -> String {
        let rows: Vec<[f64; 4]> = self
            .kept
            .iter()
            .map(|s| [s.pose.azimuth, s.pose.elevation, s.pose.distance, 45.0])
            .collect();
        serde_json::to_string_pretty(&serde_json::json!({ "rows": rows })).expect("serializable")
    }
}

/// The task's object bodies: those of its state objects and derived poses.
fn target_bodies(model: &MjModel, spec: &TaskSpec) -> Vec<usize> {
    let mut out = BTreeSet::new();
    let sources = spec
        .state
        .objects
        .iter()
        .map(|o| &o.source)
        .chain(spec.state.derived.iter().map(|d| &d.target));
    for s in sources {
        let body = match s {
            PoseSource::FreeJoint(j) => {
                name_id(model, NameKind::Joint, j).map(|j| model.jnt_bodyid()[j] as usize)
            }
            PoseSource::Body(b) | PoseSource::Mocap(b) | PoseSource::BodyPosition(b) => {
                name_id(model, NameKind::Body, b)
            }
            PoseSource::GeomLocal(g) => {
                name_id(model, NameKind::Geom, g).map(|g| model.geom_bodyid()[g] as usize)
            }
        };
        out.extend(body.filter(|&b| b != 0));
    }
    out.into_iter().collect()
}

/// Whether `body` is `root` or one of its descendants.
fn in_subtree(model: &MjModel, mut body: usize, root: usize) -> bool {
    let parent = model.body_parentid();
    loop {
        if body == root {
            return true;
        }
        if body == 0 {
            return false;
        }
        body = parent[body] as usize;
    }
}

/// Target points: the centre of every visible geom of each target body's subtree, with
/// the subtree root it belongs to.
fn target_points(
    model: &MjModel,
    data: &MjData<std::sync::Arc<MjModel>>,
    roots: &[usize],
) -> Vec<([f64; 3], usize)> {
    let group = model.geom_group();
    let rgba = model.geom_rgba();
    let mut pts = Vec::new();
    for (g, &b) in model.geom_bodyid().iter().enumerate() {
        let visible = (0..3).contains(&group[g]) && rgba[g][3] > 0.0;
        if !visible {
            continue;
        }
        if let Some(&root) = roots.iter().find(|&&r| in_subtree(model, b as usize, r)) {
            pts.push((data.geom_xpos()[g], root));
        }
    }
    pts
}

/// Fraction of `points` hidden from `eye`: the first visible geom a ray from the eye
/// towards a point hits, before reaching it, belongs to another body subtree.
pub fn occlusion(
    data: &mut MjData<std::sync::Arc<MjModel>>,
    eye: [f64; 3],
    points: &[([f64; 3], usize)],
) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let model = data.model().clone();
    let mut hidden = 0usize;
    for &(p, root) in points {
        let v = [p[0] - eye[0], p[1] - eye[1], p[2] - eye[2]];
        let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if len < 1e-9 {
            continue;
        }
        let dir = [v[0] / len, v[1] / len, v[2] / len];
        let (geom, dist) = data.ray(&eye, &dir, Some(&VISIBLE_GROUPS), true, None, None);
        if let Some(g) = geom {
            let owner = model.geom_bodyid()[g] as usize;
            // Hitting the object's own surface (on the way to its centre) is a clear view.
            if dist < len && !in_subtree(&model, owner, root) {
                hidden += 1;
            }
        }
    }
    hidden as f64 / points.len() as f64
}

/// Samples `options.candidates` poses uniformly on the sphere band (uniform azimuth and
/// uniform sine of the altitude), scores them in the task's default initial state and
/// keeps the `options.count` least occluded (ties: sampling order). Deterministic for a
/// seed.
pub fn build_pool(
    scene: &Scene,
    spec: &TaskSpec,
    options: &PoolOptions,
) -> Result<BuiltPool, AugmentError> {
    let bad =
        |message: String| AugmentError::Input(format!("camera pool for '{}': {message}", spec.id));
    if options.count == 0 || options.candidates < options.count {
        return Err(bad(format!(
            "need 0 < count ({}) <= candidates ({})",
            options.count, options.candidates
        )));
    }
    if options.distance.is_nan() || options.distance <= 0.0 {
        return Err(bad(format!("distance {} must be > 0", options.distance)));
    }
    let mut env = TaskEnv::new(scene, spec, EnvOptions::default())
        .map_err(crate::error::sim_err(&spec.id))?;
    let model = scene.model.clone();
    let roots = target_bodies(&model, spec);
    if roots.is_empty() {
        return Err(bad("the task spec names no object bodies to aim at".into()));
    }
    let points = target_points(&model, env.data(), &roots);
    if points.is_empty() {
        return Err(bad("the object bodies have no visible geoms".into()));
    }

    // Altitude above the look-at point's horizon, radians: elevation -e is altitude e.
    let (e0, e1) = (-options.elevation.0, -options.elevation.1);
    let (alt_lo, alt_hi) = (e0.min(e1).to_radians(), e0.max(e1).to_radians());
    let (az_lo, az_hi) = (
        options.azimuth.0.min(options.azimuth.1),
        options.azimuth.0.max(options.azimuth.1),
    );
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let mut candidates = Vec::with_capacity(options.candidates);
    for _ in 0..options.candidates {
        let azimuth = az_lo + (az_hi - az_lo) * rng.random::<f64>();
        let z = alt_lo.sin() + (alt_hi.sin() - alt_lo.sin()) * rng.random::<f64>();
        let pose = CameraPose {
            azimuth,
            elevation: -z.asin().to_degrees(),
            distance: options.distance,
        };
        let occ = occlusion(env.data_mut(), pose.position(), &points);
        candidates.push(ScoredPose {
            pose,
            occlusion: occ,
        });
    }
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    order.sort_by(|&a, &b| {
        candidates[a]
            .occlusion
            .total_cmp(&candidates[b].occlusion)
            .then(a.cmp(&b))
    });
    let mut kept: Vec<ScoredPose> = order[..options.count]
        .iter()
        .map(|&i| candidates[i])
        .collect();
    kept.sort_by(|a, b| {
        a.pose
            .azimuth
            .total_cmp(&b.pose.azimuth)
            .then(a.pose.elevation.total_cmp(&b.pose.elevation))
    });
    let names = roots
        .iter()
        .map(|&b| {
            model
                .id_to_name(MjtObjBase::mjOBJ_BODY, b)
                .unwrap_or_default()
                .to_owned()
        })
        .collect();
    Ok(BuiltPool {
        kept,
        candidates,
        targets: points.len(),
        target_bodies: names,
    })
}
