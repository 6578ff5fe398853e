//! Helpers shared by the CLI tests.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

/// Variables that change what the binary does: removed from every test's environment, so
/// that a developer's shell (or a Slurm / Kubernetes job running the tests) cannot leak in.
const BEHAVIOUR_ENV: &[&str] = &[
    "DEXJOCO_WORK_DIR",
    "DEXJOCO_STORE",
    "DEXJOCO_CONVERT_INPUT",
    "DEXJOCO_SEED",
    "DEXJOCO_JOBS",
    "DEXJOCO_LOG",
    "DEXJOCO_EGL_DEVICE",
    "DEXJOCO_EGL_DEVICES",
    "DEXJOCO_FIRST_FRAME_TIMEOUT",
    dexjoco_augment::FAULT_ENV,
    dexjoco_augment::STALL_ENV,
    dexjoco_augment::RENDER_DEFECT_ENV,
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_COUNT",
    "SLURM_ARRAY_TASK_MIN",
    "JOB_COMPLETION_INDEX",
];

/// The `dexjoco-data` binary under test, with [`BEHAVIOUR_ENV`] removed from its
/// environment.
pub fn dexjoco() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_dexjoco-data"));
    without_behaviour_env(&mut c);
    c
}

/// `cmd` with [`BEHAVIOUR_ENV`] removed from its environment (for a wrapper that runs
/// the binary).
pub fn without_behaviour_env(cmd: &mut Command) -> &mut Command {
    for var in BEHAVIOUR_ENV {
        cmd.env_remove(var);
    }
    cmd
}

/// A command's exit code and both streams, for assertion messages.
pub fn said(o: &Output) -> String {
    format!(
        "exit {:?}\n{}{}",
        o.status.code(),
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Runs `cmd`, asserting it exits 0; returns its output.
pub fn succeeds(cmd: &mut Command) -> Output {
    let o = cmd.output().unwrap();
    assert_eq!(o.status.code(), Some(0), "{cmd:?}: {}", said(&o));
    o
}

/// A TCP port on 127.0.0.1 that nothing listens on right now.
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// A small LeRobot v3.0 dataset made the user's way in `work`: the sample demonstration
/// `demo` (under datasets/demos/) ingested, augmented `replays` times at `size` px in the
/// fast quality with the wrist camera, converted (lerobot-doctor's checks pass on it);
/// returns the dataset folder.
pub fn sample_lerobot_dataset(work: &Path, demo: &str, replays: u32, size: u32) -> PathBuf {
    let wd = ["--work-dir", work.to_str().unwrap()];
    let demo = dexjoco_testkit::workspace_root()
        .join("datasets/demos")
        .join(demo);
    succeeds(dexjoco().args(wd).args(["-q", "ingest"]).arg(&demo));
    succeeds(
        dexjoco()
            .args(wd)
            .args(["-q", "augment"])
            .arg(work.join("ingest"))
            .args([
                "--replays",
                &replays.to_string(),
                "--size",
                &size.to_string(),
            ])
            .args(["--quality", "fast", "--camera", "handcam_rgb"]),
    );
    succeeds(dexjoco().args(wd).args(["-q", "convert"]));
    let dataset = work.join("convert/lerobot-v3");
    dexjoco_testkit::lerobot_doctor_passes(&dataset);
    dataset
}

/// A folder of DexJoCo raw episode folders (replay.zarr + videos/) for `convert`.
pub fn convert_input(dir: &Path) -> PathBuf {
    use dexjoco_core::{ArmSetup, CameraStream, Episode, FrameArray};
    let input = dir.join("episodes");
    for e in 0..2usize {
        let n = 6 + e;
        let action: Vec<Vec<f64>> = (0..n)
            .map(|k| {
                let mut r = vec![0.0; 23];
                // Moving from frame 0, never the all-zero action_rotvec row that the
                // static-frame rule would skip too.
                r[0] = 0.1 + k as f64 * 0.01;
                r[3] = 1.0;
                r
            })
            .collect();
        let mut arrays = std::collections::BTreeMap::new();
        arrays.insert(
            Episode::ACTION.into(),
            FrameArray::from_rows(&action).unwrap(),
        );
        arrays.insert(Episode::STATE.into(), FrameArray::zeros(n, 31));
        arrays.insert(
            Episode::TIMESTAMP.into(),
            Episode::regular_timestamps(n, 30.0),
        );
        let mut ep = Episode {
            id: format!("ep{e}"),
            task: "click_mouse".into(),
            prompt: String::new(),
            fps: 30.0,
            arrays,
            cameras: vec![CameraStream {
                name: "front".into(),
                video: Some("videos/front.mp4".into()),
                depth: None,
            }],
        };
        ep.compute_action_rotvec(ArmSetup::SingleArm).unwrap();
        let d = input.join("click_mouse").join(format!("episode_{e:06}"));
        fs_err::create_dir_all(d.join("videos")).unwrap();
        dexjoco_formats::raw::write_replay_zarr(&d, &ep).unwrap();
        let spec = dexjoco_video::VideoSpec {
            width: 64,
            height: 64,
            fps: 30,
            codec: dexjoco_video::Codec::DEXJOCO,
        };
        let mut w = dexjoco_video::VideoWriter::create(d.join("videos/front.mp4"), spec).unwrap();
        for k in 0..n {
            w.write_frame(&vec![(k * 20) as u8; 64 * 64 * 3]).unwrap();
        }
        w.finish().unwrap();
    }
    input
}

/// A process that stays alive while a test runs (it holds locks in tests).
pub fn sleeper() -> Child {
    Command::new("sleep")
        .arg("120")
        .spawn()
        .expect("sleep runs")
}

/// Writes a lock file naming a live process of this host, as a running command would.
pub fn lock_of(file: &Path, pid: u32) {
    let stat = fs_err::read_to_string(format!("/proc/{pid}/stat")).unwrap();
    let rest = &stat[stat.rfind(')').unwrap() + 1..];
    let started: u64 = rest.split_whitespace().nth(19).unwrap().parse().unwrap();
    let host = dexjoco_formats::lock::host_name();
    fs_err::write(
        file,
        serde_json::json!({"pid": pid, "host": host, "started": started}).to_string(),
    )
    .unwrap();
}

/// The pid of a process that has ended.
pub fn dead_pid() -> u32 {
    let mut c = Command::new("true").spawn().unwrap();
    let pid = c.id();
    c.wait().unwrap();
    pid
}

/// Runs `scripts/package.sh` with `args`; the path it prints (the bundle or the wheel).
pub fn package(args: &[&std::ffi::OsStr]) -> PathBuf {
    let out = Command::new(dexjoco_testkit::workspace_root().join("scripts/package.sh"))
        .args(args)
        .output()
        .expect("running scripts/package.sh");
    assert!(
        out.status.success(),
        "scripts/package.sh {args:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    PathBuf::from(String::from_utf8(out.stdout).unwrap().trim())
}

/// Packs this build's binary into a release bundle (`scripts/package.sh`) and extracts it
/// under `dir`; returns the bundle's folder (`dir/dexjoco-data-<version>-linux-<arch>`).
pub fn extracted_bundle(dir: &Path) -> PathBuf {
    let archive = package(&[
        "--bin".as_ref(),
        env!("CARGO_BIN_EXE_dexjoco-data").as_ref(),
        "--out".as_ref(),
        dir.as_os_str(),
    ]);
    let st = Command::new("tar")
        .arg("-xzf")
        .arg(&archive)
        .arg("-C")
        .arg(dir)
        .status()
        .unwrap();
    assert!(st.success(), "tar could not extract {}", archive.display());
    let name = archive.file_name().unwrap().to_string_lossy();
    dir.join(name.trim_end_matches(".tar.gz"))
}

/// Runs `script` (sh) in a private mount namespace with a tmpfs over the checkout
/// (`unshare -m`; the tests run as root) and an empty environment (`env -i`, PATH
/// /usr/bin:/bin), as on a machine that never had the checkout.
pub fn hidden_checkout(script: &str) -> std::process::Output {
    let checkout = dexjoco_testkit::workspace_root();
    let wrapped = format!(
        "mount -t tmpfs hidden '{}' && test ! -e '{}/Cargo.toml' && {script}",
        checkout.display(),
        checkout.display()
    );
    Command::new("unshare")
        .args(["--mount", "--propagation", "private", "--"])
        .args([
            "env",
            "-i",
            "PATH=/usr/bin:/bin",
            "HOME=/nonexistent",
            "sh",
            "-c",
        ])
        .arg(wrapped)
        .output()
        .expect("running unshare (util-linux)")
}

/// Runs the sh commands `script` (`set -e`; the first runs `dexjoco-data doctor >
/// doctor.txt` in `work`) with the checkout hidden ([`hidden_checkout`]); asserts that
/// every command succeeded, naming the job `what`; returns doctor's report.
pub fn job_with_checkout_hidden(script: &str, work: &Path, what: &str) -> String {
    let out = hidden_checkout(&format!("{script}\necho job-done"));
    let doctor = fs_err::read_to_string(work.join("doctor.txt")).unwrap_or_default();
    assert!(
        out.status.success() && String::from_utf8_lossy(&out.stdout).contains("job-done"),
        "{what} failed ({}):\nstdout: {}\nstderr: {}\ndoctor:\n{doctor}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    doctor
}

/// The sample job as a user runs it from an installed `dexjoco-data` (`prefix/bin` or a
/// link to it in `bin`, first on PATH), in `work`, with the checkout hidden and the
/// environment cleared: doctor, ingest of two demos, generate from the shipped sample,
/// augment of both, convert --merge-bimanual,
/// stats --dataset, stats --language-eval. Asserts that it finished, that doctor found
/// MuJoCo in `prefix/lib` and the sample data in `prefix/share/dexjoco-data`, and that
/// augment and the language analysis wrote their outputs; returns doctor's report.
/// `what` names the installation in failure messages.
pub fn sample_job_with_checkout_hidden(
    bin: &Path,
    prefix: &Path,
    work: &Path,
    what: &str,
) -> String {
    fs_err::create_dir_all(work).unwrap();
    let demos = prefix.join("share/dexjoco-data/datasets/demos");
    let script = format!(
        "set -e; export PATH='{bin}':$PATH; cd '{work}'
         dexjoco-data doctor > doctor.txt
         dexjoco-data -q ingest '{demos}/click_mouse' '{demos}/bimanual_unlock_ipad'
         dexjoco-data -q generate --task click_mouse --count 2
         dexjoco-data -q -j 2 augment dexjoco-work/ingest dexjoco-work/generate --replays 1 --size 32 --quality fast
         dexjoco-data -q convert --merge-bimanual > convert.txt
         dexjoco-data -q stats --dataset dexjoco-work/augment > stats.txt
         dexjoco-data -q stats --language-eval > language.txt",
        bin = bin.display(),
        work = work.display(),
        demos = demos.display(),
    );
    let doctor =
        job_with_checkout_hidden(&script, work, &format!("the sample job from the {what}"));
    // doctor found MuJoCo and the sample data beside the binary, not in the checkout.
    let lib = prefix.join("lib").canonicalize().unwrap();
    assert!(
        doctor.contains(&format!("{}/libmujoco.so.3.17.0", lib.display())),
        "{doctor}"
    );
    assert!(
        doctor.contains("datasets (from share/dexjoco-data beside the binary"),
        "{doctor}"
    );
    // Every stage wrote its output.
    let report = work.join("dexjoco-work/augment/augment_report.json");
    let report: serde_json::Value =
        serde_json::from_str(&fs_err::read_to_string(report).unwrap()).unwrap();
    // click_mouse has two sample episodes, unlock_ipad one, generate made two; one replay
    // each, the generated ones among them.
    let replays = report["replays"].as_array().unwrap();
    assert_eq!(replays.len(), 5, "{report}");
    let generated = work.join("dexjoco-work/generate/click_mouse/generate_report.json");
    assert!(generated.is_file(), "generate's report from the {what}");
    assert_eq!(
        replays
            .iter()
            // ingest names episodes by their content's hash, generate by their number
            .filter(|r| r["episode"].as_str().unwrap().starts_with("episode_"))
            .count(),
        2,
        "the generated episodes replayed by augment: {report}"
    );
    assert!(
        fs_err::read_to_string(work.join("language.txt"))
            .unwrap()
            .contains("Jensen"),
        "the language analysis of the {what}'s examples"
    );
    doctor
}

/// A policy server process (`tests/python/policy_server.py`: openpi's own
/// `WebsocketPolicyServer` from the reference code, in the reference venv), killed on drop.
pub struct PolicyServer {
    child: Child,
    /// Its port on 127.0.0.1.
    pub port: u16,
}

impl PolicyServer {
    /// Starts `policy_server.py <args>` on a free port; returns once it listens.
    pub fn start(args: &[&str]) -> Self {
        let port = free_port();
        let script = dexjoco_testkit::workspace_root().join("tests/python/policy_server.py");
        let mut child = Command::new(dexjoco_testkit::reference_python())
            .arg(script)
            .args(["--port", &port.to_string()])
            .args(args)
            .env(
                "DEXJOCO_REFERENCE_CODE",
                dexjoco_testkit::reference_code_dir(),
            )
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("the reference venv's Python runs");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        assert!(line.starts_with("listening"), "policy server: {line:?}");
        Self { child, port }
    }
}

impl Drop for PolicyServer {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Processes whose environment holds `DEXJOCO_TEST_MARK=<mark>` (set by the test on the
/// command it starts, inherited by its children) and whose command line holds the word
/// `word` (e.g. `eval-worker`; empty: any).
pub fn processes_marked(mark: &str, word: &str) -> Vec<u32> {
    let needle = format!("DEXJOCO_TEST_MARK={mark}");
    fs_err::read_dir("/proc")
        .unwrap()
        .flatten()
        .filter_map(|e| e.file_name().to_str()?.parse::<u32>().ok())
        .filter(|pid| {
            let has = |file: &str, what: &[u8]| {
                std::fs::read(format!("/proc/{pid}/{file}"))
                    .is_ok_and(|b| b.split(|&c| c == 0).any(|v| v == what))
            };
            has("environ", needle.as_bytes())
                && (word.is_empty() || has("cmdline", word.as_bytes()))
        })
        .collect()
}
