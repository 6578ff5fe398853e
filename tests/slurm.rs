//! `augment` on a real Slurm cluster, from an extracted release bundle as a cluster runs
//! it: a one-node cluster (Debian's `slurm-wlm` and `munge`: slurmctld + slurmd, all
//! state under one temporary folder) started by `scripts/slurm/local-cluster.sh`, the
//! sharded job submitted by the bundle's `share/dexjoco-data/slurm/submit.sh` (a job array
//! of 4 shards running its `augment.sbatch`, then the finalize job with
//! `--dependency=afterok`), every job running the bundle's own binary, and the output
//! compared byte for byte with one unsharded run; then the same for `generate`
//! (`submit.sh --stage generate`). The daemons it started are stopped (by pid) and the folder removed, also
//! when the test fails. Needs root and the packages (`scripts/setup.sh --python`).

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

fn root() -> PathBuf {
    dexjoco_testkit::workspace_root()
}

/// Stops the cluster when dropped (also on a failed assertion).
struct Cluster {
    dir: PathBuf,
}

impl Cluster {
    fn start(dir: PathBuf) -> Self {
        let out = Command::new(root().join("scripts/slurm/local-cluster.sh"))
            .arg("start")
            .arg(&dir)
            .output()
            .expect("running scripts/slurm/local-cluster.sh");
        assert!(
            out.status.success(),
            "the test cluster did not start (needs root and Debian's slurm-wlm and munge: \
             scripts/setup.sh --python installs them):\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        Self { dir }
    }

    fn conf(&self) -> PathBuf {
        self.dir.join("slurm.conf")
    }
}

impl Drop for Cluster {
    fn drop(&mut self) {
        let out = Command::new(root().join("scripts/slurm/local-cluster.sh"))
            .arg("stop")
            .arg(&self.dir)
            .output();
        if let Ok(o) = out
            && !o.status.success()
        {
            eprintln!(
                "stopping the test cluster failed: {}",
                String::from_utf8_lossy(&o.stderr)
            );
        }
    }
}

/// The sample episode the bundle carries, augmented into `out`.
fn augment_args(bundle: &Path, out: &Path) -> Vec<String> {
    let episode = bundle.join("share/dexjoco-data/datasets/demos/click_mouse/episode_000000");
    vec![
        episode.display().to_string(),
        "--replays".into(),
        "4".into(),
        "--size".into(),
        "32".into(),
        "--quality".into(),
        "fast".into(),
        "--out".into(),
        out.display().to_string(),
    ]
}

#[test]
fn a_sharded_augment_on_a_real_slurm_cluster_equals_one_run() {
    let tmp = tempfile::tempdir().unwrap();
    // The bundle lies on the "shared file system" (here: a folder every job sees).
    let bundle = common::extracted_bundle(tmp.path());
    let bin = bundle.join("bin/dexjoco-data");

    // The reference: one unsharded run.
    let single = tmp.path().join("single");
    let out = Command::new(&bin)
        .args(["-q", "-j", "2", "augment"])
        .args(augment_args(&bundle, &single))
        .env("DEXJOCO_LOG", "warn")
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");

    // The cluster lives in a world-readable folder (munged insists), here under /tmp.
    let dir = std::env::temp_dir().join(format!("dexjoco-slurm-{}", std::process::id()));
    let cluster = Cluster::start(dir.clone());
    let sharded = tmp.path().join("sharded");
    let logs = tmp.path().join("logs");
    let out = Command::new(bundle.join("share/dexjoco-data/slurm/submit.sh"))
        .args(["--wait", "--logs"])
        .arg(&logs)
        .arg("4")
        .args(augment_args(&bundle, &sharded))
        .env("SLURM_CONF", cluster.conf())
        .env_remove("DEXJOCO_BIN")
        .env("DEXJOCO_LOG", "warn")
        .env("SUBMIT_POLL_SECONDS", "0.5")
        .current_dir(tmp.path())
        .output()
        .unwrap();
    let job_logs: Vec<String> = fs_err::read_dir(&logs)
        .map(|rd| {
            rd.flatten()
                .map(|e| {
                    format!(
                        "--- {}\n{}",
                        e.file_name().to_string_lossy(),
                        fs_err::read_to_string(e.path()).unwrap_or_default()
                    )
                })
                .collect()
        })
        .unwrap_or_default();
    assert!(
        out.status.success(),
        "{out:?}\nstderr: {}\njob logs:\n{}",
        String::from_utf8_lossy(&out.stderr),
        job_logs.join("\n")
    );
    // Four shards and the finalize ran as Slurm jobs, each into the shared folder.
    let mut names: Vec<String> = fs_err::read_dir(&logs)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names.len(), 5, "{names:?}");
    assert_eq!(
        names.iter().filter(|n| n.starts_with("augment-")).count(),
        4
    );
    let text = job_logs.join("\n");
    for k in 0..4 {
        assert!(
            text.contains(&format!("augment shard {k}/4:")),
            "shard {k} did not run:\n{text}"
        );
    }
    assert!(
        text.contains("(0 rendered now"),
        "the finalize rendered:\n{text}"
    );
    // Every job ran the bundle's binary, found by submit.sh beside itself.
    assert_eq!(
        text.matches(&format!(
            "running {}",
            bin.canonicalize().unwrap().display()
        ))
        .count(),
        5,
        "{text}"
    );
    assert_eq!(
        dexjoco_testkit::file_tree(&sharded),
        dexjoco_testkit::file_tree(&single)
    );

    sharded_generate_equals_one_run(tmp.path(), &bundle, &cluster);
    drop(cluster);
    assert!(!dir.exists(), "the cluster's folder is left behind");
}

/// The same submit script and finalize step run `generate` (issue #46): 3 shards of
/// click_mouse from the bundle's sample data, then the finalize, equal to one run.
fn sharded_generate_equals_one_run(tmp: &Path, bundle: &Path, cluster: &Cluster) {
    let bin = bundle.join("bin/dexjoco-data");
    let gen_args = ["--task", "click_mouse", "--count", "5", "--seed", "3"];
    let gen_single = tmp.join("gen-single");
    let out = Command::new(&bin)
        .args(["-q", "-j", "2", "generate"])
        .args(gen_args)
        .arg("--out")
        .arg(&gen_single)
        .env("DEXJOCO_LOG", "warn")
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let gen_sharded = tmp.join("gen-sharded");
    let gen_logs = tmp.join("gen-logs");
    let out = Command::new(bundle.join("share/dexjoco-data/slurm/submit.sh"))
        .args(["--wait", "--stage", "generate", "--logs"])
        .arg(&gen_logs)
        .arg("3")
        .args(gen_args)
        .arg("--out")
        .arg(&gen_sharded)
        .env("SLURM_CONF", cluster.conf())
        .env_remove("DEXJOCO_BIN")
        .env("DEXJOCO_LOG", "warn")
        .env("SUBMIT_POLL_SECONDS", "0.5")
        .current_dir(tmp)
        .output()
        .unwrap();
    let text: String = fs_err::read_dir(&gen_logs)
        .map(|rd| {
            rd.flatten()
                .map(|e| fs_err::read_to_string(e.path()).unwrap_or_default())
                .collect()
        })
        .unwrap_or_default();
    assert!(
        out.status.success(),
        "{out:?}\nstderr: {}\njob logs:\n{text}",
        String::from_utf8_lossy(&out.stderr)
    );
    for k in 0..3 {
        assert!(text.contains(&format!("generate shard {k}/3:")), "{text}");
    }
    let generated = |d: &Path| {
        let mut t = dexjoco_testkit::file_tree(&d.join("click_mouse"));
        t.remove("generate_times.json");
        t.retain(|k, _| !k.starts_with(".surplus/"));
        t
    };
    let (a, b) = (generated(&gen_single), generated(&gen_sharded));
    assert_eq!(
        a.keys().filter(|k| k.ends_with("/generate.json")).count(),
        5
    );
    assert!(
        a == b,
        "sharded generate differs: {:?}",
        a.keys()
            .filter(|k| a.get(*k) != b.get(*k))
            .collect::<Vec<_>>()
    );
}
