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
    fs_err::create_dir_all(&work).unwrap();
    let demos = bundle.join("share/dexjoco-data/datasets/demos");
    let script = format!(
        "set -e; export PATH='{links}':$PATH; cd '{work}'
         dexjoco-data doctor > doctor.txt
         dexjoco-data -q ingest '{demos}/click_mouse' '{demos}/bimanual_unlock_ipad'
         dexjoco-data -q -j 2 augment dexjoco-work/ingest --replays 1 --size 32 --quality fast
         dexjoco-data -q convert --merge-bimanual > convert.txt
         dexjoco-data -q stats --dataset dexjoco-work/augment > stats.txt
         dexjoco-data -q stats --language-eval > language.txt
         echo sample-job-done",
        links = links.display(),
        work = work.display(),
        demos = demos.display(),
    );
    let out = common::hidden_checkout(&script);
    let doctor = fs_err::read_to_string(work.join("doctor.txt")).unwrap_or_default();
    assert!(
        out.status.success() && String::from_utf8_lossy(&out.stdout).contains("sample-job-done"),
        "the sample job failed from the bundle ({}):\nstdout: {}\nstderr: {}\ndoctor:\n{doctor}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    // doctor found MuJoCo in the bundle and the sample data beside the binary, not in the
    // checkout.
    let lib = bundle.join("lib").canonicalize().unwrap();
    assert!(
        doctor.contains(&format!("{}/libmujoco.so.3.17.0", lib.display())),
        "{doctor}"
    );
    assert!(
        doctor.contains("datasets (from share/dexjoco-data beside the binary"),
        "{doctor}"
    );
    assert!(!doctor.contains(&root().display().to_string()), "{doctor}");
    // Every stage wrote its output.
    let report = work.join("dexjoco-work/augment/augment_report.json");
    let report: serde_json::Value =
        serde_json::from_str(&fs_err::read_to_string(report).unwrap()).unwrap();
    // click_mouse has two sample episodes, unlock_ipad one; one replay each.
    assert_eq!(report["replays"].as_array().unwrap().len(), 3, "{report}");
    assert!(work.join("dexjoco-work/convert").is_dir());
    assert!(
        fs_err::read_to_string(work.join("language.txt"))
            .unwrap()
            .contains("Jensen"),
        "the language analysis of the bundle's examples"
    );
}
