//! The release bundle runs where the checkout is not: `scripts/package.sh` packs this
//! build's binary, the bundle is extracted into a temporary folder and run in a private
//! mount namespace with a tmpfs over the checkout (`unshare -m`; the tests run as root)
//! and with the environment cleared (`env -i` and a minimal PATH). There `doctor` finds
//! MuJoCo, EGL and the sample data inside the bundle, and the whole sample job (ingest,
//! augment, convert, stats) succeeds, run through a symbolic link as a container image
//! installs it.

use std::path::PathBuf;
use std::process::Command;

mod common;

fn root() -> PathBuf {
    dexjoco_testkit::workspace_root()
}

#[test]
fn the_bundle_runs_the_sample_job_with_the_checkout_hidden_and_no_environment() {
    let tmp = tempfile::tempdir().unwrap();
    let opt = tmp.path().join("opt");
    fs_err::create_dir_all(&opt).unwrap();
    let bundle = common::extracted_bundle(&opt);
    let name = bundle.file_name().unwrap().to_string_lossy().into_owned();
    assert!(
        name.starts_with("dexjoco-data-") && name.ends_with("-linux-x86_64"),
        "{name}"
    );
    for part in [
        "bin/dexjoco-data",
        "lib/libmujoco.so.3.17.0",
        "share/dexjoco-data/datasets/demos/click_mouse",
        "share/dexjoco-data/datasets/examples/language-eval",
        "share/dexjoco-data/slurm/submit.sh",
        "share/dexjoco-data/deploy/Dockerfile",
        "share/dexjoco-data/deploy/dexjoco-data.def",
        "licenses/MuJoCo-LICENSE",
        "licenses/LICENSE-MIT",
        "licenses/THIRD-PARTY-RUST.md",
        "README.md",
    ] {
        assert!(bundle.join(part).exists(), "the bundle lacks {part}");
    }
    let third_party = fs_err::read_to_string(bundle.join("licenses/THIRD-PARTY-RUST.md")).unwrap();
    assert!(
        third_party.contains("| mujoco-rs |") && third_party.contains("| zarrs |"),
        "the crate list misses crates compiled in"
    );
    // Stripped, and MuJoCo found through the bundle's own lib/.
    let readelf = Command::new("readelf")
        .arg("-d")
        .arg(bundle.join("bin/dexjoco-data"))
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&readelf.stdout).contains("$ORIGIN/../lib"));

    // As a container image installs it: a link on PATH to the bundle's binary.
    let links = tmp.path().join("usr-local-bin");
    fs_err::create_dir_all(&links).unwrap();
    std::os::unix::fs::symlink(bundle.join("bin/dexjoco-data"), links.join("dexjoco-data"))
        .unwrap();
    let work = tmp.path().join("work");
    let doctor = common::sample_job_with_checkout_hidden(&links, &bundle, &work, "bundle");
    assert!(!doctor.contains(&root().display().to_string()), "{doctor}");
    assert!(work.join("dexjoco-work/convert").is_dir());
}
