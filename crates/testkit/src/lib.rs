//! Test support for the dexjoco-data crates (a dev-dependency only).
//!
//! - [`python`]: the interpreter of the cached venv of real readers (numpy, SciPy, zarr,
//!   mcap, lerobot...), made by `scripts/setup.sh --python`. Tests that need it fail
//!   with a hint when it is missing: they are never skipped.
//! - [`upstream_dir`], [`reference_scene_dir`]: the DexJoCo reference scenes at
//!   `../shared/dexjoco-upstream`.
//! - [`reference_python`], [`run_reference_python`], [`reference_code_dir`]: the DexJoCo
//!   reference code (`../shared/third_party/dexjoco-8d23b0f`) and the venv with its pins
//!   that runs its environments (`tests/python/dexjoco_reference.py` drives them), under
//!   a pinned arithmetic setting ([`reference_arithmetic`]).
//! - [`hostile`]: generated hostile inputs (mutated files) and a bounded, deterministic
//!   runner that checks a parser neither panics nor hangs on them.

pub mod hostile;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The workspace root.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .canonicalize()
        .expect("workspace root")
}

/// A venv's Python: `$<variable>`, else the path `scripts/setup.sh <flag>` recorded in
/// `.deps/<file>`. Panics naming the venv (`what`) and both places when neither exists.
fn recorded_python(variable: &str, file: &str, what: &str, flag: &str) -> PathBuf {
    if let Some(p) = std::env::var_os(variable) {
        return p.into();
    }
    let recorded = workspace_root().join(".deps").join(file);
    if let Ok(p) = fs_err::read_to_string(&recorded) {
        let p = PathBuf::from(p.trim());
        if p.is_file() {
            return p;
        }
    }
    panic!(
        "{what} is missing: run `scripts/test.sh` (or `scripts/setup.sh {flag}`) first; \
         looked at ${variable} and {}",
        recorded.display()
    );
}

/// The Python of the test venv: `$DEXJOCO_PYTHON`, else the path `scripts/setup.sh
/// --python` recorded in `.deps/python-path`. Panics with a hint when neither exists.
pub fn python() -> PathBuf {
    recorded_python(
        "DEXJOCO_PYTHON",
        "python-path",
        "the test venv of real readers",
        "--python",
    )
}

/// The Python of the Warp renderer's venv: `$DEXJOCO_WARP_PYTHON`, else the path
/// `scripts/setup.sh --warp` recorded in `.deps/warp-python-path`. Panics with a hint when
/// neither exists.
pub fn warp_python() -> PathBuf {
    recorded_python(
        "DEXJOCO_WARP_PYTHON",
        "warp-python-path",
        "the Warp renderer's venv",
        "--warp",
    )
}

/// The Python of the reference venv (the DexJoCo reference environments' pins):
/// `$DEXJOCO_REFERENCE_PYTHON`, else `.deps/reference-python-path` written by
/// `scripts/setup.sh --python`. Panics with a hint when neither exists.
pub fn reference_python() -> PathBuf {
    recorded_python(
        "DEXJOCO_REFERENCE_PYTHON",
        "reference-python-path",
        "the reference venv",
        "--python",
    )
}

/// The code no registry carries (`../shared/third_party`, or `$DEXJOCO_THIRD_PARTY`).
/// Panics, saying clearly that it is absent, when not found.
pub fn third_party_dir() -> PathBuf {
    let candidates = [
        std::env::var_os("DEXJOCO_THIRD_PARTY").map(PathBuf::from),
        Some(workspace_root().join("../shared/third_party")),
    ];
    candidates.into_iter().flatten().find(|p| p.join(REFERENCE_CODE).is_dir()).unwrap_or_else(|| {
        panic!(
            "the DexJoCo reference code is absent: expected ../shared/third_party/{REFERENCE_CODE} beside \
             the checkout (or set DEXJOCO_THIRD_PARTY)"
        )
    })
}

/// The folder of the DexJoCo reference code under [`third_party_dir`].
pub const REFERENCE_CODE: &str = "dexjoco-8d23b0f";

/// The DexJoCo reference code (environments, converter, openpi's statistics).
pub fn reference_code_dir() -> PathBuf {
    third_party_dir().join(REFERENCE_CODE)
}

/// Runs a script of `tests/python/` in the reference venv, with `DEXJOCO_REFERENCE_CODE`
/// and `DEXJOCO_UPSTREAM` set for `dexjoco_reference.py`; returns stdout, panicking with
/// stderr when it fails.
pub fn run_reference_python(script: &str, args: &[&str]) -> String {
    run_reference_python_as(script, args, &reference_arithmetic())
}

/// [`run_reference_python`] under a named arithmetic setting of the reference side
/// (`tests/python/reference_arithmetic.py`: numpy's SIMD loops and OpenBLAS's kernels).
pub fn run_reference_python_as(script: &str, args: &[&str], arithmetic: &str) -> String {
    let mut cmd = Command::new(reference_python());
    cmd.env("DEXJOCO_REFERENCE_CODE", reference_code_dir())
        .env("DEXJOCO_UPSTREAM", upstream_dir())
        .env("DEXJOCO_REFERENCE_ARITHMETIC", arithmetic);
    run_script(cmd, script, args)
}

/// The arithmetic setting the reference side runs under: `$DEXJOCO_REFERENCE_ARITHMETIC`,
/// default `avx2` (numpy without its AVX-512 loops, OpenBLAS's Haswell kernels: the same
/// bits on every CPU with AVX2 and FMA; `tests/python/reference_arithmetic.py` lists the
/// settings, docs/testing.md how to run the parity tests under each).
pub fn reference_arithmetic() -> String {
    std::env::var("DEXJOCO_REFERENCE_ARITHMETIC")
        .ok()
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "avx2".to_owned())
}

/// Runs a Python script of `tests/python/` (or any path) with arguments in the test venv;
/// returns stdout, panicking with stderr when it fails.
pub fn run_python(script: &str, args: &[&str]) -> String {
    run_script(Command::new(python()), script, args)
}

fn run_script(mut python: Command, script: &str, args: &[&str]) -> String {
    let path = {
        let p = Path::new(script);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            workspace_root().join("tests/python").join(script)
        }
    };
    let out = python
        .arg(&path)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", path.display()));
    assert!(
        out.status.success(),
        "{} {:?} failed ({}):\n{}",
        path.display(),
        args,
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("utf-8 output")
}

/// Runs a script and parses its stdout as JSON.
pub fn run_python_json(script: &str, args: &[&str]) -> serde_json::Value {
    let out = run_python(script, args);
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("{script} printed no JSON ({e}):\n{out}"))
}

/// The DexJoCo reference scene files (`../shared/dexjoco-upstream`, or
/// `$DEXJOCO_UPSTREAM`). Panics, saying clearly that they are absent, when not found.
pub fn upstream_dir() -> PathBuf {
    let candidates = [
        std::env::var_os("DEXJOCO_UPSTREAM").map(PathBuf::from),
        Some(workspace_root().join("../shared/dexjoco-upstream")),
    ];
    candidates.into_iter().flatten().find(|p| p.join("xmls").is_dir()).unwrap_or_else(|| {
        panic!(
            "the DexJoCo reference scenes are absent: expected ../shared/dexjoco-upstream beside the checkout \
             (or set DEXJOCO_UPSTREAM)"
        )
    })
}

/// The DexJoCo reference scenes' MJCF folder (`--scene-dir`): `xmls/` of [`upstream_dir`].
pub fn reference_scene_dir() -> PathBuf {
    upstream_dir().join("xmls")
}

/// Every file below `dir` (path relative to `dir` -> bytes), for comparing outputs byte
/// for byte.
pub fn file_tree(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fn walk(root: &Path, p: &Path, out: &mut BTreeMap<String, Vec<u8>>) {
        let entries = fs_err::read_dir(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        for e in entries {
            let p = e.expect("directory entry").path();
            if p.is_dir() {
                walk(root, &p, out);
            } else {
                let rel = p.strip_prefix(root).expect("below root");
                let bytes = fs_err::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
                out.insert(rel.to_string_lossy().into_owned(), bytes);
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

/// Runs `lerobot-doctor` 0.2.0 (community checks of LeRobot datasets, in the test venv)
/// on the LeRobot dataset at `root`. Panics when it exits with an error (`--ci
/// --fail-on fail`: a FAIL), naming the failing checks, or when it warns of a video file
/// whose frame count disagrees with its episodes'.
pub fn lerobot_doctor_passes(root: &Path) {
    let python = python();
    let doctor = python.with_file_name("lerobot-doctor");
    let out = Command::new(&doctor)
        .arg("check")
        .arg(root)
        .args(["--ci", "--fail-on", "fail", "--json"])
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", doctor.display()));
    let text = String::from_utf8_lossy(&out.stdout);
    let report: serde_json::Value = serde_json::from_str(&text).unwrap_or_else(|e| {
        panic!(
            "lerobot-doctor printed no JSON for {} ({e}):\n{text}\n{}",
            root.display(),
            String::from_utf8_lossy(&out.stderr)
        )
    });
    let messages: Vec<String> = report["checks"]
        .as_array()
        .into_iter()
        .flatten()
        .flat_map(|c| {
            c["messages"]
                .as_array()
                .into_iter()
                .flatten()
                .map(move |m| format!("{} {}: {}", m["severity"], c["name"], m["message"]))
        })
        .filter(|m| !m.starts_with("\"PASS\""))
        .collect();
    assert!(
        out.status.success() && report["overall_severity"] != "FAIL",
        "lerobot-doctor fails {} ({}):\n{}",
        root.display(),
        out.status,
        messages.join("\n")
    );
    let frame_counts: Vec<&String> = messages
        .iter()
        .filter(|m| m.contains("frames, expected"))
        .collect();
    assert!(
        frame_counts.is_empty(),
        "lerobot-doctor: a video's frame count disagrees with its episodes in {}:\n{frame_counts:?}",
        root.display()
    );
}
