//! `dexjoco-data bench generate`: generation attempts per second on one core, ours against
//! the same loop written in Python on the DexJoCo reference environments
//! (`tests/python/generate_loop.py`), on the same attempts with the same source segments.

use std::path::Path;
use std::process::Command;
use std::time::Instant;

use anyhow::{Context, bail};
use dexjoco_core::{PoseSource, TaskSpec};
use dexjoco_generate::{Attempt, AttemptOptions, SourceDemo, attempt, current_targets};
use dexjoco_scripted::{self as scripted, Variant};
use dexjoco_sim::{EnvOptions, Scene, SceneSource, TaskEnv, load_task_scene};
use rand::{Rng, SeedableRng};
use serde::Serialize;

use crate::cli::BenchGenerateArgs;
use dexjoco_cli::cli::GlobalArgs;
use dexjoco_cli::exit::ExitStatus;

/// One side's run of a task's attempts.
#[derive(Debug, Serialize)]
struct Side {
    attempts: usize,
    successes: usize,
    steps: usize,
    seconds: f64,
}

impl Side {
    fn per_step_us(&self) -> f64 {
        1e6 * self.seconds / self.steps.max(1) as f64
    }

    fn cell(&self) -> String {
        format!(
            "{}/{} | {} | {:.3} | {:.1}",
            self.successes,
            self.attempts,
            self.steps,
            self.seconds / self.attempts.max(1) as f64,
            self.per_step_us()
        )
    }
}

/// A task's measurement.
#[derive(Debug, Serialize)]
struct TaskRun {
    task: String,
    sources: usize,
    ours: Side,
    python: Option<Side>,
}

/// Runs `bench generate`.
pub fn run(global: &GlobalArgs, args: &BenchGenerateArgs) -> anyhow::Result<ExitStatus> {
    let scenes = dexjoco_cli::commands::reference_scene_dir()
        .context("the DexJoCo reference scenes are not found (../shared/dexjoco-upstream beside the checkout, or $DEXJOCO_UPSTREAM)")?;
    let python = if args.no_reference {
        Err("--no-reference".to_owned())
    } else {
        reference_python()
    };
    if let Err(why) = &python {
        outln!("Python loop skipped: {why}");
    }
    let mut runs = Vec::new();
    for task in &args.tasks {
        let spec = TaskSpec::builtin(task).with_context(|| format!("unknown task '{task}'"))?;
        if spec.setup.arms() != 1 {
            bail!("{task}: bench generate measures single-arm tasks only");
        }
        let scene = load_task_scene(&SceneSource::Dir(scenes.clone()), spec)?;
        let sources = scripted_sources(&scene, spec, args.sources)?;
        let (ours, attempts) = ours(&scene, spec, &sources, args.attempts, global.seed)?;
        let python = match &python {
            Ok((py, env)) => Some(python_side(py, env, spec, &scene, &sources, &attempts)?),
            Err(_) => None,
        };
        runs.push(TaskRun {
            task: task.clone(),
            sources: sources.len(),
            ours,
            python,
        });
    }
    print_table(&runs);
    let dir = global.work_dir.join("bench");
    fs_err::create_dir_all(&dir)?;
    let json = serde_json::to_vec_pretty(&runs).expect("serializable");
    dexjoco_formats::write_atomic(&dir.join("generate.json"), &json)?;
    Ok(ExitStatus::Success)
}

/// Scripted plans from `scripted --seed 1000`'s first resets that succeed, prepared.
fn scripted_sources(scene: &Scene, spec: &TaskSpec, n: usize) -> anyhow::Result<Vec<SourceDemo>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1000);
    let mut sources = Vec::new();
    for k in 0..n {
        let s0 = TaskEnv::sample_initial_state(scene, spec, &mut || rng.random::<f64>())?;
        let id = format!("{}_scripted_seed1000_{k}", spec.id);
        let plan = scripted::plan(scene, spec, &s0, &id, Variant::Demo)?;
        if plan.success_at.is_some()
            && let Ok(s) = SourceDemo::prepare(scene, spec, &plan.episode, 0)
        {
            sources.push(s);
        }
    }
    if sources.is_empty() {
        bail!("{}: no scripted plan could serve as a source", spec.id);
    }
    Ok(sources)
}

/// Our attempts `0..n` of `seed`'s resets, one after another on this thread.
fn ours(
    scene: &Scene,
    spec: &TaskSpec,
    sources: &[SourceDemo],
    n: usize,
    seed: u64,
) -> anyhow::Result<(Side, Vec<Attempt>)> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let resets = (0..n)
        .map(|_| TaskEnv::sample_initial_state(scene, spec, &mut || rng.random::<f64>()))
        .collect::<Result<Vec<_>, _>>()?;
    let options = AttemptOptions::default();
    let start = Instant::now();
    let attempts = resets
        .into_iter()
        .enumerate()
        .map(|(i, r)| attempt(scene, spec, sources, r, i, seed, &options))
        .collect::<Result<Vec<_>, _>>()?;
    let seconds = start.elapsed().as_secs_f64();
    let side = Side {
        attempts: n,
        successes: attempts
            .iter()
            .filter(|a| a.planned.success_at.is_some())
            .count(),
        steps: attempts.iter().map(|a| a.planned.episode.len()).sum(),
        seconds,
    };
    Ok((side, attempts))
}

/// The reference venv's Python and the environment its scripts need, or why not.
fn reference_python() -> Result<(std::path::PathBuf, Vec<(String, std::path::PathBuf)>), String> {
    let py = dexjoco_cli::locate::reference_python()
        .map(|l| l.path)
        .ok_or("no reference venv (scripts/setup.sh --python, or $DEXJOCO_REFERENCE_PYTHON)")?;
    let checkout = dexjoco_cli::locate::checkout().ok_or("not run from a source checkout")?;
    let third_party = std::env::var_os("DEXJOCO_THIRD_PARTY")
        .map_or_else(|| checkout.join("../shared/third_party"), Into::into);
    let code = third_party.join("dexjoco-8d23b0f");
    if !code.join("scripts/replay_demos_zarr.py").is_file() {
        return Err(format!("the reference code is absent ({})", code.display()));
    }
    let upstream = checkout.join("../shared/dexjoco-upstream");
    Ok((
        py,
        vec![
            ("DEXJOCO_REFERENCE_CODE".into(), code),
            ("DEXJOCO_UPSTREAM".into(), upstream),
            (
                "DEXJOCO_PYTHON_SCRIPTS".into(),
                checkout.join("tests/python"),
            ),
        ],
    ))
}

/// The MuJoCo element the Python loop reads a state object's pose from.
fn object_ref(spec: &TaskSpec, name: &str) -> serde_json::Value {
    let source = spec
        .state
        .objects
        .iter()
        .find(|o| o.name == name)
        .map(|o| &o.source);
    let (kind, n) = match source {
        Some(PoseSource::FreeJoint(j)) => ("joint", j.as_str()),
        Some(PoseSource::GeomLocal(g)) => ("geom", g.as_str()),
        Some(PoseSource::Body(b) | PoseSource::Mocap(b) | PoseSource::BodyPosition(b)) => {
            ("body", b.as_str())
        }
        None => ("body", name),
    };
    serde_json::json!({ "kind": kind, "name": n })
}

/// The job of the Python loop: per attempt its restored state, targets at reset and the
/// segments our run chose.
fn python_job(
    spec: &TaskSpec,
    scene: &Scene,
    sources: &[SourceDemo],
    attempts: &[Attempt],
) -> anyhow::Result<serde_json::Value> {
    let flat = |t: &dexjoco_generate::ArmTarget| {
        let mut v = vec![0.0; 7];
        t.pose.write(&mut v);
        v.extend_from_slice(&t.hand);
        v
    };
    let mut jobs = Vec::new();
    for a in attempts {
        let env = TaskEnv::from_initial_state(scene, spec, &a.reset, EnvOptions::default())?;
        let segments: Vec<serde_json::Value> = a
            .provenance
            .iter()
            .map(|p| {
                let i = spec.subtasks.iter().position(|s| s.id == p.subtask).expect("a subtask");
                let source = sources.iter().find(|s| s.id == p.source).expect("a source");
                let seg = &source.segments[i];
                let mut pose = vec![0.0; 7];
                seg.object_pose.write(&mut pose);
                serde_json::json!({
                    "subtask": p.subtask,
                    "object": object_ref(spec, &spec.subtasks[i].object),
                    "object_pose": pose,
                    "arms": seg.arms,
                    "targets": seg.targets.iter().map(|row| row.iter().map(flat).collect::<Vec<_>>()).collect::<Vec<_>>(),
                })
            })
            .collect();
        jobs.push(serde_json::json!({
            "state0": a.planned.episode.array(dexjoco_core::Episode::STATE).map(|s| s.row(0).to_vec()),
            "targets0": current_targets(&env).iter().map(flat).collect::<Vec<_>>(),
            "segments": segments,
        }));
    }
    let o = AttemptOptions::default();
    Ok(serde_json::json!({
        "task": spec.id,
        "action_width": spec.setup.action_dim(),
        "options": {
            "bridge_m_per_step": o.bridge_m_per_step,
            "bridge_rad_per_step": o.bridge_rad_per_step,
            "bridge_min_steps": o.bridge_min_steps,
        },
        "attempts": jobs,
    }))
}

/// Runs the Python loop on our attempts.
fn python_side(
    py: &Path,
    env: &[(String, std::path::PathBuf)],
    spec: &TaskSpec,
    scene: &Scene,
    sources: &[SourceDemo],
    attempts: &[Attempt],
) -> anyhow::Result<Side> {
    let tmp = tempfile::tempdir()?;
    let job = tmp.path().join("job.json");
    let json = python_job(spec, scene, sources, attempts)?;
    fs_err::write(&job, serde_json::to_vec(&json)?)?;
    let scripts = &env
        .iter()
        .find(|(k, _)| k == "DEXJOCO_PYTHON_SCRIPTS")
        .expect("set")
        .1;
    let mut cmd = Command::new(py);
    cmd.arg(scripts.join("generate_loop.py"))
        .arg(&job)
        .current_dir(scripts);
    for (k, v) in env {
        cmd.env(k, v);
    }
    let out = cmd.output().context("running the Python loop")?;
    if !out.status.success() {
        bail!(
            "the Python loop failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).with_context(|| {
        format!(
            "the Python loop printed: {}",
            String::from_utf8_lossy(&out.stdout)
        )
    })?;
    let n = |k: &str| v[k].as_u64().unwrap_or(0) as usize;
    Ok(Side {
        attempts: n("attempts"),
        successes: n("successes"),
        steps: n("steps"),
        seconds: v["seconds"].as_f64().unwrap_or(f64::NAN),
    })
}

fn print_table(runs: &[TaskRun]) {
    outln!(
        "| task | sources | ours: successes | steps | s / attempt | us / step | Python: successes | steps | s / attempt | us / step | Python / ours (per step) |"
    );
    outln!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in runs {
        let (py, ratio) = match &r.python {
            Some(p) => (
                p.cell(),
                format!("{:.1}x", p.per_step_us() / r.ours.per_step_us()),
            ),
            None => ("- | - | - | -".into(), "-".into()),
        };
        outln!(
            "| {} | {} | {} | {py} | {ratio} |",
            r.task,
            r.sources,
            r.ours.cell()
        );
    }
}
