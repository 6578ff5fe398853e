//! `dexjoco-dev bench convert` and `bench generate` end to end, with the real Python
//! tools they compare against (lerobot's writer and reader, the DexJoCo reference
//! converter and environments).

use std::path::Path;
use std::process::{Command, Output};

/// Settings read from the environment that would change what the binary does.
const BEHAVIOUR_ENV: &[&str] = &[
    "DEXJOCO_WORK_DIR",
    "DEXJOCO_SEED",
    "DEXJOCO_JOBS",
    "DEXJOCO_LOG",
];

fn run(args: &[&str], cwd: &Path) -> Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_dexjoco-dev"));
    for var in BEHAVIOUR_ENV {
        c.env_remove(var);
    }
    c.args(args).current_dir(cwd).output().expect("binary runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn the_user_command_line_runs_inside_the_developer_binary() {
    let dir = tempfile::tempdir().unwrap();
    let out = run(&["user", "--version"], dir.path());
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).starts_with("dexjoco-data "),
        "{}",
        text(&out.stdout)
    );
    let help = text(&run(&["--help"], dir.path()).stdout);
    assert!(help.contains("bench"), "{help}");
    let bench = text(&run(&["bench", "--help"], dir.path()).stdout);
    for sub in ["convert", "generate", "fidelity"] {
        assert!(bench.contains(sub), "{bench}");
    }
}

#[test]
fn bench_convert_times_random_reads_of_ours_and_the_reference_converters_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "bench",
        "convert",
        "--episodes",
        "2",
        "--frames",
        "30",
        "--size",
        "64",
        "--memory-episodes",
        "2",
        "--memory-frames",
        "5",
        "--no-lerobot",
        "--read-items",
        "5",
    ];
    let out = run(&args, dir.path());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    for row in [
        "| LeRobot v3.0 dataset | backend | MB | ms per random item (median) | mean |",
        "| dexjoco-data convert (stream copy) | torchcodec |",
        "| dexjoco-data convert (stream copy) | pyav |",
        "| DexJoCo reference converter (AV1, GOP 2) | torchcodec |",
        "| DexJoCo reference converter (AV1, GOP 2) | pyav |",
    ] {
        assert!(table.contains(row), "{row} missing:\n{table}");
    }
    let json: serde_json::Value = serde_json::from_str(
        &fs_err::read_to_string(dir.path().join("dexjoco-work/bench/convert.json")).unwrap(),
    )
    .unwrap();
    let reads = json["random_reads"].as_array().unwrap();
    assert_eq!(reads.len(), 4, "{json}");
    for r in reads {
        assert!(r["ms_median"].as_f64().unwrap() > 0.0, "{r}");
        assert!(r["bytes"].as_u64().unwrap() > 0, "{r}");
    }
}

#[test]
fn bench_generate_runs_ours_and_the_python_loop_on_the_same_attempts() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "bench",
        "generate",
        "--task",
        "click_mouse",
        "--attempts",
        "2",
        "--sources",
        "1",
    ];
    let out = run(&args, dir.path());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    assert!(table.contains("| click_mouse | 1 | "), "{table}");
    let json: serde_json::Value = serde_json::from_str(
        &fs_err::read_to_string(dir.path().join("dexjoco-work/bench/generate.json")).unwrap(),
    )
    .unwrap();
    let run = &json[0];
    assert_eq!(run["ours"]["attempts"], 2);
    assert_eq!(run["python"]["attempts"], 2, "{run}");
    // The same attempts: the steps differ only where ours waits for a subtask's end.
    let (ours, py) = (
        run["ours"]["steps"].as_f64().unwrap(),
        run["python"]["steps"].as_f64().unwrap(),
    );
    assert!(ours > 500.0 && (py - ours).abs() / ours < 0.1, "{run}");
}
