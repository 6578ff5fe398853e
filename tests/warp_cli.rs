//! `augment --renderer warp` end to end on Warp's CPU device: the sample demonstration on
//! its built-in scene and the DexJoCo reference scene of hammer_nail, replays that
//! `convert` turns into a dataset lerobot reads, the same bytes whatever the worker count
//! and batch size, records naming the renderer, a resume with the other renderer refused.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

use common::{dexjoco, said, succeeds};

/// `augment` of the hammer_nail sample with the Warp renderer on the CPU, into `out`.
fn augment_warp(out: &Path, extra: &[&str]) -> Command {
    let mut c = dexjoco();
    c.current_dir(dexjoco_testkit::workspace_root())
        .args(["-q"])
        .args(extra)
        .args(["augment", "datasets/demos/hammer_nail"])
        .args(["--replays", "2", "--size", "64", "--quality", "fast"])
        .args([
            "--renderer",
            "warp",
            "--warp-device",
            "cpu",
            "--warp-python",
        ])
        .arg(dexjoco_testkit::warp_python())
        .arg("--out")
        .arg(out);
    c
}

/// Every file of the replays (videos, arrays) by path, without the reports and records,
/// which name times and machines.
fn replay_bytes(out: &Path) -> Vec<(String, Vec<u8>)> {
    dexjoco_testkit::file_tree(out)
        .into_iter()
        .filter(|(p, _)| p.contains("videos/") || p.contains("replay.zarr"))
        .collect()
}

fn record(out: &Path, replay: &str) -> serde_json::Value {
    let p = out.join("hammer_nail").join(replay).join("replay.json");
    serde_json::from_str(&fs_err::read_to_string(p).unwrap()).unwrap()
}

/// lerobot 0.6.1 loads the converted dataset: every frame, both cameras.
fn lerobot_reads(dataset: &Path, episodes: u64, cameras: usize) -> serde_json::Value {
    dexjoco_testkit::lerobot_doctor_passes(dataset);
    let loaded = dexjoco_testkit::run_python_json(
        "lerobot_v3_load.py",
        &[dataset.to_str().unwrap(), "pyav"],
    );
    assert_eq!(loaded["num_episodes"], episodes, "{loaded}");
    assert_eq!(loaded["camera_keys"].as_array().unwrap().len(), cameras);
    loaded
}

#[test]
fn warp_replays_are_deterministic_convert_and_refuse_a_resume_with_opengl() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let with_wrist = ["--camera", "handcam_rgb"];
    succeeds(augment_warp(&a, &["-j", "1"]).args(with_wrist));
    succeeds(
        augment_warp(&b, &["-j", "2"])
            .args(with_wrist)
            .args(["--warp-batch", "3"]),
    );
    let (ta, tb) = (replay_bytes(&a), replay_bytes(&b));
    assert!(
        ta.len() >= 2 * 3,
        "two replays, two videos and arrays each: {}",
        ta.len()
    );
    assert!(ta == tb, "worker count and batch size changed the bytes");

    let r = record(&a, "episode_000000__r00");
    let renderer = r["renderer"].as_str().unwrap();
    assert!(renderer.starts_with("warp 3.17.0 on cpu"), "{renderer}");
    assert_eq!(r["success"], true, "{r}");
    let settings = fs_err::read_to_string(a.join("augment_settings.json")).unwrap();
    assert!(settings.contains("\"renderer\": \"warp\""), "{settings}");

    // The folder is Warp's: the OpenGL renderer may not add to it.
    let mut gl = dexjoco();
    gl.current_dir(dexjoco_testkit::workspace_root())
        .args(["-q", "augment", "datasets/demos/hammer_nail"])
        .args(["--replays", "3", "--size", "64", "--quality", "fast"])
        .args(with_wrist)
        .arg("--out")
        .arg(&a);
    let refused = gl.output().unwrap();
    assert_ne!(refused.status.code(), Some(0), "{}", said(&refused));
    let text = said(&refused);
    assert!(
        text.contains("renderer") && text.contains("--overwrite"),
        "{text}"
    );
    assert!(!a.join("hammer_nail/episode_000000__r02").exists());

    let dataset = dir.path().join("ds");
    succeeds(
        dexjoco()
            .args(["-q", "convert", "--input"])
            .arg(&a)
            .arg("--out")
            .arg(&dataset),
    );
    let loaded = lerobot_reads(&dataset, 2, 2);
    // Frames are images of the scene, not blank: every camera's mean is neither black
    // nor white on the first and last item.
    let items = loaded["items"].as_array().unwrap();
    for it in [&items[0], items.last().unwrap()] {
        for (key, mean) in it["images"].as_object().unwrap() {
            let m: Vec<f64> = mean
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            assert!(m.iter().all(|&c| c > 10.0 && c < 245.0), "{key}: {m:?}");
        }
    }
}

#[test]
fn warp_renders_the_reference_hammer_nail_scene_into_a_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let scenes: PathBuf = dexjoco_testkit::reference_scene_dir();
    // A demonstration made in the reference scene: a scripted one.
    let demos = dir.path().join("scripted");
    succeeds(
        dexjoco()
            .args(["-q", "scripted", "--task", "hammer_nail", "--episodes", "1"])
            .arg("--scene-dir")
            .arg(&scenes)
            .arg("--out")
            .arg(&demos),
    );
    let out = dir.path().join("aug");
    let mut c = dexjoco();
    c.args(["-q", "-j", "2", "augment"])
        .arg(demos.join("hammer_nail"))
        .args(["--replays", "2", "--size", "64", "--quality", "fast"])
        .args([
            "--renderer",
            "warp",
            "--warp-device",
            "cpu",
            "--warp-python",
        ])
        .arg(dexjoco_testkit::warp_python())
        .arg("--scene-dir")
        .arg(&scenes)
        .arg("--out")
        .arg(&out);
    succeeds(&mut c);
    let r = record(&out, "episode_000000__r01");
    assert!(r["renderer"].as_str().unwrap().starts_with("warp"), "{r}");
    assert_eq!(r["success"], true, "{r}");
    let dataset = dir.path().join("ds");
    succeeds(
        dexjoco()
            .args(["-q", "convert", "--input"])
            .arg(&out)
            .arg("--out")
            .arg(&dataset),
    );
    lerobot_reads(&dataset, 2, 1);
}

/// The processes (other than this one) whose environment holds `marker`.
fn processes_marked(marker: &str) -> Vec<String> {
    let mut left = Vec::new();
    for e in fs_err::read_dir("/proc").unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if !name.bytes().all(|b| b.is_ascii_digit()) || name == std::process::id().to_string() {
            continue;
        }
        let Ok(env) = std::fs::read(e.path().join("environ")) else {
            continue;
        };
        if env.windows(marker.len()).any(|w| w == marker.as_bytes()) {
            let cmd = std::fs::read(e.path().join("cmdline")).unwrap_or_default();
            left.push(format!(
                "{name}: {}",
                String::from_utf8_lossy(&cmd[..cmd.len().min(80)])
            ));
        }
    }
    left
}

/// A worker that is not MuJoCo Warp's: it answers `hello` and `open` as the worker does,
/// then replies to a render with a header claiming 2^60 bytes of images, followed by an
/// endless stream of zeros.
const LYING_WORKER: &str = r#"
import json, struct, sys
H = struct.Struct("<IQ")
out = sys.stdout.buffer
def read(n):
    b = sys.stdin.buffer.read(n)
    if len(b) < n:
        sys.exit(0)
    return b
while True:
    n, p = H.unpack(read(12))
    req = json.loads(read(n)); read(p)
    if req["op"] == "hello":
        body = {"ok": True, "device": "cpu", "device_name": "cpu", "versions":
                {"mujoco": "3.17.0", "mujoco-warp": "3.17.0", "warp-lang": "1.19.0"}}
    elif req["op"] == "open":
        body = {"ok": True, "open_seconds": 0.0}
    else:
        b = json.dumps({"ok": True, "worlds": 1, "times": {}}).encode()
        out.write(H.pack(len(b), 1 << 60) + b)
        zeros = bytes(1 << 20)
        while True:
            out.write(zeros)
    b = json.dumps(body).encode()
    out.write(H.pack(len(b), 0) + b)
    out.flush()
"#;

/// A worker's reply is bounded by what was asked for (a claim of 2^60 bytes is refused
/// from its header, not read into memory), and a worker that hangs is killed with the
/// process that started it: no Python is left running after augment ends.
#[test]
fn a_lying_or_hanging_warp_worker_fails_the_run_by_name_and_leaves_no_process() {
    let dir = tempfile::tempdir().unwrap();
    let fake = dir.path().join("python");
    let shebang = format!("#!{}\n", dexjoco_testkit::python().display());
    fs_err::write(&fake, shebang + LYING_WORKER).unwrap();
    use std::os::unix::fs::PermissionsExt;
    fs_err::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    let marker = format!("DEXJOCO_TEST_MARKER=lying-{}", std::process::id());
    let started = std::time::Instant::now();
    let o = augment_warp(&dir.path().join("lying"), &["-j", "1"])
        .env("DEXJOCO_TEST_MARKER", marker.split_once('=').unwrap().1)
        .args(["--first-frame-timeout", "120", "--warp-python"])
        .arg(&fake)
        .output()
        .unwrap();
    let text = said(&o);
    assert_eq!(o.status.code(), Some(1), "{text}");
    assert!(
        text.contains("Warp worker") && text.contains("1152921504606846976"),
        "{text}"
    );
    assert!(started.elapsed().as_secs() < 100, "{:?}", started.elapsed());
    std::thread::sleep(std::time::Duration::from_millis(500));
    assert_eq!(processes_marked(&marker), Vec::<String>::new());

    // The real worker, its augment worker stalled after the renderer opened (as a hung
    // driver would): killed at the deadline, and its Python with it.
    let marker = format!("DEXJOCO_TEST_MARKER=stalled-{}", std::process::id());
    let o = augment_warp(&dir.path().join("stalled"), &["-j", "1"])
        .env("DEXJOCO_TEST_MARKER", marker.split_once('=').unwrap().1)
        .env(dexjoco_augment::STALL_ENV, "all")
        .args(["--first-frame-timeout", "40"])
        .output()
        .unwrap();
    let text = said(&o);
    assert_eq!(o.status.code(), Some(1), "{text}");
    // The Warp renderer opened (its Python was running) before the worker was killed.
    assert!(
        text.contains("on the Warp renderer (warp 3.17.0 on cpu)"),
        "{text}"
    );
    assert!(!text.contains("EGL"), "{text}");
    std::thread::sleep(std::time::Duration::from_millis(500));
    assert_eq!(processes_marked(&marker), Vec::<String>::new());
}
