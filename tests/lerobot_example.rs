//! The walkthrough of docs/evaluate-a-policy.md kept working, end to end with real parts:
//! `augment` renders one sample demonstration, `convert` writes LeRobot v3.0, LeRobot's own
//! `lerobot-train` trains an ACT policy for a few steps (random-init backbone: nothing
//! downloaded), `examples/serve_lerobot_policy.py` serves the checkpoint through openpi's
//! websocket server, `eval` runs one episode against it, and `stats --success-table` reads
//! the output. It checks the plumbing, not the policy's skill.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use common::{dexjoco, free_port, said, sample_lerobot_dataset, succeeds};

/// The test venv's console script `name` (beside its Python).
fn venv_script(name: &str) -> PathBuf {
    let python = dexjoco_testkit::python();
    let script = python.parent().unwrap().join(name);
    assert!(
        script.is_file(),
        "{} is missing: the test venv lacks it; run scripts/setup.sh --python",
        script.display()
    );
    script
}

/// The example server process (killed on drop), its log in `log`.
struct ExampleServer(Child);

impl ExampleServer {
    fn start(checkpoint: &Path, port: u16, log: &Path) -> Self {
        let script = dexjoco_testkit::workspace_root().join("examples/serve_lerobot_policy.py");
        let openpi_src = dexjoco_testkit::reference_code_dir().join("openpi/src");
        let child = Command::new(dexjoco_testkit::python())
            .arg(script)
            .arg("--checkpoint")
            .arg(checkpoint)
            .args(["--camera", "base=observation.images.third_person"])
            .args(["--camera", "wrist=observation.images.handcam_rgb"])
            .args(["--host", "127.0.0.1", "--port", &port.to_string()])
            .arg("--openpi-src")
            .arg(openpi_src)
            .stdout(Stdio::null())
            .stderr(fs_err::File::create(log).unwrap().into_parts().0)
            .spawn()
            .expect("the test venv's Python runs");
        Self(child)
    }
}

impl Drop for ExampleServer {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// LeRobot's own trainer, a few ACT steps on the CPU; returns the checkpoint folder.
fn train(dataset: &Path, train: &Path) -> PathBuf {
    let o = succeeds(
        Command::new(venv_script("lerobot-train"))
            .env("HF_HUB_OFFLINE", "1")
            .env("WANDB_MODE", "disabled")
            .arg("--dataset.repo_id=local/click_mouse")
            .arg(format!("--dataset.root={}", dataset.display()))
            .args([
                "--policy.type=act",
                "--policy.device=cpu",
                "--policy.push_to_hub=false",
                "--policy.pretrained_backbone_weights=null",
                "--policy.chunk_size=30",
                "--policy.n_action_steps=30",
                "--batch_size=2",
                "--steps=2",
                "--save_freq=2",
                "--num_workers=0",
                "--wandb.enable=false",
            ])
            .arg(format!("--output_dir={}", train.display())),
    );
    let checkpoint = train.join("checkpoints/last/pretrained_model");
    assert!(
        checkpoint.join("model.safetensors").is_file(),
        "no checkpoint: {}",
        said(&o)
    );
    checkpoint
}

#[test]
fn a_lerobot_policy_trained_on_our_dataset_is_served_by_the_example_and_evaluated() {
    let tmp = tempfile::tempdir().unwrap();
    // The dataset: one sample demonstration, one randomized replay, 64 px.
    let dataset = sample_lerobot_dataset(
        &tmp.path().join("work"),
        "click_mouse/episode_000000",
        1,
        64,
    );
    let checkpoint = train(&dataset, &tmp.path().join("train_act"));

    // The example serves it; eval runs one episode against it.
    let port = free_port();
    let log = tmp.path().join("server.log");
    let _server = ExampleServer::start(&checkpoint, port, &log);
    let out = tmp.path().join("eval/click_mouse_rand_full_seed0");
    let o = dexjoco()
        .args(["-q", "eval", "--task", "click_mouse", "--episodes", "1"])
        .args([
            "--rand-full",
            "--host",
            "127.0.0.1",
            "--port",
            &port.to_string(),
        ])
        .args(["--render-size", "64x64", "--quality", "fast", "--no-videos"])
        .args(["--server-wait", "180", "-j", "1", "--step-cap", "150"])
        .arg("--output")
        .arg(&out)
        .output()
        .unwrap();
    let server_log = fs_err::read_to_string(&log).unwrap_or_default();
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}\nserver log:\n{server_log}",
        said(&o)
    );

    // One episode, answered by the ACT checkpoint: its metadata and whole chunks.
    let episode = fs_err::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| {
            p.file_name()
                .unwrap()
                .to_string_lossy()
                .starts_with("episode_00_")
        })
        .unwrap_or_else(|| panic!("no episode folder in {}", out.display()));
    let record: serde_json::Value =
        serde_json::from_slice(&fs_err::read(episode.join("episode.json")).unwrap()).unwrap();
    let metadata = &record["server_metadata"];
    assert_eq!(metadata["policy_type"], "act", "{record}");
    assert_eq!(metadata["chunk_size"], 30, "{record}");
    assert_eq!(metadata["action_dim"], 22, "{record}");
    // One short episode: click_mouse's 30 warm-up steps and the policy's 120.
    assert_eq!(record["step_cap"], 150, "{record}");
    let steps = record["steps"].as_u64().unwrap() + record["warmup_steps"].as_u64().unwrap();
    assert!(steps == 150 || record["ended_by"] != "step_cap", "{record}");
    assert!(record["chunks"].as_u64().unwrap() > 0, "{record}");

    // stats reads the output as it is.
    let o = succeeds(
        dexjoco()
            .args(["stats", "--success-table"])
            .arg(tmp.path().join("eval"))
            .arg("--out")
            .arg(tmp.path().join("stats")),
    );
    assert!(said(&o).contains("Click Mouse"), "{}", said(&o));
}
