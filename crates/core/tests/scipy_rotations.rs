//! Rotations agree with SciPy (in the cached venv) to 1e-12 on random and edge-case inputs.

use dexjoco_core::{quat_wxyz_to_rotvec, rotvec_to_quat_wxyz};
use rand::{Rng, SeedableRng};
use std::f64::consts::PI;

fn edge_quats() -> Vec<[f64; 4]> {
    let s = std::f64::consts::FRAC_1_SQRT_2;
    vec![
        [1.0, 0.0, 0.0, 0.0],   // identity
        [-1.0, 0.0, 0.0, 0.0],  // identity, negative w
        [0.0, 0.0, 0.0, 0.0],   // zero quaternion -> zero rotvec (DexJoCo convention)
        [0.0, 1.0, 0.0, 0.0],   // 180 degrees about x
        [0.0, 0.0, 0.0, -1.0],  // 180 degrees about -z
        [0.0, s, s, 0.0],       // 180 degrees about a diagonal
        [1e-9, 0.0, 1.0, 0.0],  // just under 180 degrees
        [-1e-9, 0.0, 1.0, 0.0], // just over (negative w)
        [s, 0.0, 0.0, s],       // 90 degrees about z
        [-s, 0.0, 0.0, -s],     // the same, negative w
        [-0.3, 0.1, -0.2, 0.9], // negative w, general
        [1.0, 1e-7, 0.0, 0.0],  // tiny angle (Taylor branch)
        [1.0, 4e-4, 0.0, 0.0],  // angle just under the 1e-3 branch point
        [1.0, 6e-4, 0.0, 0.0],  // and just over
        [5.0, 0.0, 0.0, 0.0],   // unnormalized identity
        [2.0, -2.0, 1.0, 3.0],  // unnormalized general
        [1e-6, 0.0, 0.0, 0.0],  // tiny but nonzero norm
    ]
}

fn edge_rotvecs() -> Vec<[f64; 3]> {
    vec![
        [0.0, 0.0, 0.0],
        [1e-9, 0.0, 0.0],
        [9.9e-4, 0.0, 0.0],
        [1.1e-3, 0.0, 0.0],
        [PI, 0.0, 0.0],
        [0.0, -PI, 0.0],
        [4.0, 1.0, -2.0], // angle > pi
        [0.0, 0.0, 2.0 * PI],
    ]
}

#[test]
fn rotations_match_scipy() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2026);
    let mut quats = edge_quats();
    for _ in 0..2000 {
        quats.push(std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
    }
    let mut rotvecs = edge_rotvecs();
    for _ in 0..2000 {
        let scale = rng.random_range(0.0..4.0);
        rotvecs.push(std::array::from_fn(|_| rng.random_range(-1.0..1.0) * scale));
    }
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("rotations.json");
    fs_err::write(
        &input,
        serde_json::json!({ "quats": quats, "rotvecs": rotvecs }).to_string(),
    )
    .unwrap();
    let out = dexjoco_testkit::run_python_json("rotations_scipy.py", &[input.to_str().unwrap()]);

    let expected_rotvec = out["rotvec"].as_array().unwrap();
    assert_eq!(expected_rotvec.len(), quats.len());
    let mut worst = 0.0f64;
    for (q, e) in quats.iter().zip(expected_rotvec) {
        let ours = quat_wxyz_to_rotvec(*q);
        for k in 0..3 {
            let err = (ours[k] - e[k].as_f64().unwrap()).abs();
            worst = worst.max(err);
            assert!(err <= 1e-12, "quat {q:?}: ours {ours:?}, SciPy {e:?}");
        }
    }
    let expected_quat = out["quat"].as_array().unwrap();
    for (r, e) in rotvecs.iter().zip(expected_quat) {
        let ours = rotvec_to_quat_wxyz(*r);
        for k in 0..4 {
            let err = (ours[k] - e[k].as_f64().unwrap()).abs();
            worst = worst.max(err);
            assert!(err <= 1e-12, "rotvec {r:?}: ours {ours:?}, SciPy {e:?}");
        }
    }
    eprintln!("largest difference from SciPy: {worst:e}");
}
