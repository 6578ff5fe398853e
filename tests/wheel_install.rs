//! The Python wheel installs as a user installs it: `scripts/package.sh --wheel` builds it
//! with maturin (from this build's target folder: `--profile dev --native`), a fresh venv
//! gets it from the file alone (`pip install --no-index`), and with the checkout hidden
//! and the environment cleared (as the bundle test does) the venv's `dexjoco-data` finds
//! MuJoCo and the sample data inside the venv and runs the sample job. With the
//! `ffmpeg` extra (imageio-ffmpeg's static build, from the wheelhouse `scripts/setup.sh
//! --python` fills) and no system ffmpeg on PATH, it encodes and probes with that one.
//! `pip uninstall` then leaves the venv as it was.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

/// Every file and link under `dir` (relative), byte-compiled caches left out.
fn files_under(dir: &Path) -> BTreeSet<String> {
    let mut out = BTreeSet::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in fs_err::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let rel = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
            if rel.contains("__pycache__") {
                continue;
            }
            if p.is_dir() && !p.is_symlink() {
                stack.push(p);
            }
            out.insert(rel);
        }
    }
    out
}

fn is_empty_dir(dir: &Path) -> bool {
    fs_err::read_dir(dir).is_ok_and(|mut d| d.next().is_none())
}

fn pip(venv: &Path, args: &[&str]) {
    common::succeeds(
        Command::new(venv.join("bin/python"))
            .args(["-m", "pip", "--disable-pip-version-check", "-q"])
            .args(args),
    );
}

fn build_wheel(dist: &Path) -> PathBuf {
    let args = ["--wheel", "--profile", "dev", "--native", "--out"];
    let mut args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_ref()).collect();
    args.push(dist.as_os_str());
    common::package(&args)
}

#[test]
fn pip_installs_the_wheel_which_runs_the_sample_job_with_the_checkout_hidden() {
    let tmp = tempfile::tempdir().unwrap();
    let wheel = build_wheel(&tmp.path().join("dist"));
    let name = wheel.file_name().unwrap().to_string_lossy().into_owned();
    assert!(
        name.starts_with("dexjoco_data-") && name.contains("-py3-none-") && name.ends_with(".whl"),
        "{name}"
    );

    let venv = tmp.path().join("venv");
    let made = Command::new(dexjoco_testkit::python())
        .args(["-m", "venv"])
        .arg(&venv)
        .status()
        .unwrap();
    assert!(made.success(), "python -m venv failed");
    let before = files_under(&venv);
    pip(&venv, &["install", "--no-index", wheel.to_str().unwrap()]);
    // The bundle's layout inside the venv.
    for part in [
        "bin/dexjoco-data",
        "lib/libmujoco.so.3.17.0",
        "share/dexjoco-data/datasets/demos/click_mouse",
        "share/dexjoco-data/datasets/examples/language-eval",
        "share/dexjoco-data/licenses/MuJoCo-LICENSE",
        "share/dexjoco-data/licenses/THIRD-PARTY-RUST.md",
        "share/dexjoco-data/slurm/submit.sh",
    ] {
        assert!(venv.join(part).exists(), "the installed wheel lacks {part}");
    }

    sample_job(&venv, &tmp.path().join("work"));
    ffmpeg_extra_job(&venv, &wheel, &tmp.path().join("alone"));

    // Uninstalled, nothing of it is left.
    pip(
        &venv,
        &["uninstall", "-y", "dexjoco-data", "imageio-ffmpeg"],
    );
    // pip removes what it recorded, never a parent folder it created: a venv had no
    // share/, so that one empty folder may stay (as for every package with data files).
    let after = files_under(&venv);
    let left: Vec<_> = after
        .difference(&before)
        .filter(|p| !(*p == "share" && is_empty_dir(&venv.join(p))))
        .collect();
    assert!(left.is_empty(), "pip uninstall left {left:?}");
}

/// The sample job from the venv's `bin/`, the system's ffmpeg on PATH, checkout hidden.
fn sample_job(venv: &Path, work: &Path) {
    let doctor = common::sample_job_with_checkout_hidden(&venv.join("bin"), venv, work, "wheel");
    assert!(doctor.contains("found: on PATH"), "{doctor}");
    assert!(
        work.join("dexjoco-work/convert/lerobot-v3/meta/info.json")
            .is_file()
    );
}

/// The `ffmpeg` extra installed from the wheelhouse alone; augment and convert with it,
/// nothing but the venv's `bin/` on PATH (no system ffmpeg, no ffprobe).
fn ffmpeg_extra_job(venv: &Path, wheel: &Path, alone: &Path) {
    let (bin, demos) = (
        venv.join("bin"),
        venv.join("share/dexjoco-data/datasets/demos"),
    );
    let wheelhouse =
        fs_err::read_to_string(dexjoco_testkit::workspace_root().join(".deps/wheelhouse-path"))
            .expect("run scripts/setup.sh --python: it fills the wheelhouse");
    let with_extra = format!("{}[ffmpeg]", wheel.display());
    pip(
        venv,
        &[
            "install",
            "--no-index",
            "--find-links",
            wheelhouse.trim(),
            &with_extra,
        ],
    );
    fs_err::create_dir_all(alone).unwrap();
    let script = format!(
        "set -e; export PATH='{bin}'; cd '{alone}'
         dexjoco-data doctor > doctor.txt
         dexjoco-data -q ingest '{demos}/click_mouse'
         dexjoco-data -q augment dexjoco-work/ingest --replays 1 --size 32 --quality fast
         dexjoco-data -q convert",
        bin = bin.display(),
        alone = alone.display(),
        demos = demos.display(),
    );
    let doctor =
        common::job_with_checkout_hidden(&script, alone, "augment and convert with imageio-ffmpeg");
    assert!(
        doctor.contains("imageio_ffmpeg/binaries/ffmpeg-")
            && doctor.contains("found: imageio-ffmpeg's static build")
            && doctor.contains("ffprobe: none"),
        "{doctor}"
    );
    let info: serde_json::Value = serde_json::from_str(
        &fs_err::read_to_string(alone.join("dexjoco-work/convert/lerobot-v3/meta/info.json"))
            .unwrap(),
    )
    .unwrap();
    assert_eq!(info["total_episodes"], 2, "{info}");
}
