"""The DexJoCo reference code, run headless for the parity tests (reference venv only).

The reference code lives outside the project (`$DEXJOCO_REFERENCE_CODE`, as
`testkit::run_reference_python` sets it; default ../shared/third_party/dexjoco-8d23b0f
beside the checkout; the scenes: `$DEXJOCO_UPSTREAM`, default ../shared/dexjoco-upstream). Its environments
load their scenes from beside their own source, so this module makes a scratch copy of
the `dexjoco` package in the cache (never in the project), with the scene folder and the
camera pools of `$DEXJOCO_UPSTREAM` linked in and the one line MuJoCo 3.17.0 needs
adapted (`mj_fullM(model, M, data.qM)` became `mj_fullM(model, data, M)` in 3.5). At
import time, for this process only: the 30 Hz pacing sleep is a no-op and the renderer
returns a 1x1 black image (no OpenGL context; physics and success logic are untouched;
`DEXJOCO_REFERENCE_RENDER=1` keeps the reference's own EGL renderer,
`DEXJOCO_REFERENCE_SLEEP=1` its 30 Hz pacing).

Used as a library (`make_env`, `replay`, `replay_job`, `record`) or from the command line:

    python dexjoco_reference.py replay --task T --episode DIR --out OUT.npz [--extend N]
        [--nudge M]
    python dexjoco_reference.py batch --jobs JOBS.json --out DIR [--tag TAG]
    python dexjoco_reference.py summarize --jobs JOBS.json --out DIR --primary TAG
        [--members TAG,...]
    python dexjoco_reference.py record --task T --episode DIR --out DIR

Every command runs under the arithmetic `$DEXJOCO_REFERENCE_ARITHMETIC` names (default
`avx2`, see `reference_arithmetic.py`): numpy's SIMD loops and OpenBLAS's kernels pinned
so the reference computes the same bits on every CPU.

writes the reference replay script's own trajectory (`scripts/replay_demos_zarr.py`'s
`_replay_single_demo`) as arrays: `state` (steps x width, the observation before each
step), `succeed`, `terminated` (per step), and prints a JSON summary (first success,
first failure, the state blocks).
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import json
import os
import shutil
import sys
import time
from pathlib import Path

import reference_arithmetic  # before numpy: pins its SIMD loops and OpenBLAS's kernels

import numpy as np

REFERENCE = "dexjoco-8d23b0f"
_FULLM_OLD = "mujoco.mj_fullM(model, M, data.qM)"
_FULLM_NEW = "mujoco.mj_fullM(model, data, M)"
CALM_MARGIN = 10


_SHARED = Path(__file__).resolve().parents[3] / "shared"


def _required_dir(var: str, default: Path, what: str) -> Path:
    value = Path(os.environ[var]) if os.environ.get(var) else default
    if not value.is_dir():
        sys.exit(f"error: {what} not found at {value}: put it there or set ${var}")
    return value


def reference_code() -> Path:
    """The DexJoCo reference code checkout (`$DEXJOCO_REFERENCE_CODE`)."""
    return _required_dir(
        "DEXJOCO_REFERENCE_CODE", _SHARED / "third_party" / REFERENCE, "the DexJoCo reference code"
    )


def upstream() -> Path:
    """The DexJoCo reference scenes and camera pools (`$DEXJOCO_UPSTREAM`)."""
    return _required_dir("DEXJOCO_UPSTREAM", _SHARED / "dexjoco-upstream", "the DexJoCo reference scenes")


def _source_digest(package: Path, up: Path) -> str:
    h = hashlib.sha256(str(up.resolve()).encode())
    for p in sorted(package.rglob("*.py")):
        h.update(str(p.relative_to(package)).encode())
        h.update(p.read_bytes())
    return h.hexdigest()[:12]


def scratch_copy() -> Path:
    """The folder to put on sys.path: a scratch copy of the reference package with the
    scenes linked in and mj_fullM adapted. Made once per source digest, atomically."""
    code, up = reference_code(), upstream()
    package = code / "dexjoco" / "dexjoco"
    cache = Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "dexjoco-data"
    root = cache / f"reference-{REFERENCE}-{_source_digest(package, up)}"
    if (root / ".complete").is_file():
        return root
    tmp = cache / f".{root.name}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    shutil.copytree(package, tmp / "dexjoco")
    envs = tmp / "dexjoco" / "sim" / "envs"
    os.symlink(up / "xmls", envs / "xmls")
    for pool in ("replay_cameras.npy", "replay_cameras_2.npy"):
        os.symlink(up / pool, envs / pool)
    opspace = tmp / "dexjoco" / "sim" / "controllers" / "opspace.py"
    text = opspace.read_text()
    if text.count(_FULLM_OLD) != 1:
        sys.exit(f"error: {opspace}: expected one `{_FULLM_OLD}` to adapt to MuJoCo 3.17")
    opspace.write_text(text.replace(_FULLM_OLD, _FULLM_NEW))
    (tmp / ".complete").write_text("")
    try:
        os.rename(tmp, root)
    except OSError:  # another process made it first
        shutil.rmtree(tmp, ignore_errors=True)
    return root


def _disable_multiccd_on_load():
    """Every reference env disables multi-point convex collision after loading its model,
    as MuJoCo 3.4 (the reference's pin) had it off and 3.17 has it on; our TaskEnv does
    the same by default (`EnvOptions::disable_multiccd`). `DEXJOCO_REFERENCE_MULTICCD=1`
    leaves 3.17's default."""
    if os.environ.get("DEXJOCO_REFERENCE_MULTICCD") == "1":
        return
    import mujoco
    from dexjoco.sim import mujoco_gym_env

    original = mujoco_gym_env.MujocoGymEnv.__init__

    def init(self, *args, **kwargs):
        original(self, *args, **kwargs)
        self._model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_MULTICCD

    mujoco_gym_env.MujocoGymEnv.__init__ = init


class _HeadlessRenderer:
    """Stands in for the reference's MujocoRenderer: no OpenGL, a 1x1 black image."""

    def __init__(self, model, data, *args, **kwargs):
        self.model, self.data = model, data

    def render(self, *args, **kwargs):
        return np.zeros((1, 1, 3), dtype=np.uint8)

    def close(self):
        pass


def _load():
    os.environ.setdefault("TQDM_DISABLE", "1")  # the replay script's progress bar
    sys.path.insert(0, str(scratch_copy()))
    if os.environ.get("DEXJOCO_REFERENCE_SLEEP") != "1":
        time.sleep = lambda _seconds: None  # the envs pace themselves to 30 Hz
    import dexjoco.sim.rendering as rendering

    # `DEXJOCO_REFERENCE_RENDER=1`: the reference's own renderer (EGL), for the tests
    # that compare its images.
    if os.environ.get("DEXJOCO_REFERENCE_RENDER") != "1":
        rendering.MujocoRenderer = _HeadlessRenderer
    _disable_multiccd_on_load()
    from dexjoco.tasks.mappings import CONFIG_MAPPING

    return CONFIG_MAPPING


CONFIG_MAPPING = _load()


def make_env(task: str, seed: int = 0):
    """The task's environment as the reference replay builds it (policy mode, no
    randomization), reset."""
    config = CONFIG_MAPPING[task]()
    env = config.get_environment(
        policy_mode=True,
        render_mode="rgb_array",
        randomize=False,
        randomize_dynamics=False,
        seed=seed,
    )
    env.reset()
    return config, env


@functools.lru_cache(maxsize=None)
def state_blocks(task: str) -> list[tuple[str, int]]:
    """The state vector's blocks (proprio key, width) in order (an env made once per
    task and process)."""
    config, env = make_env(task)
    try:
        state = env.unwrapped._compute_observation()["state"]
        return [(k, int(np.asarray(state[k]).size)) for k in config.proprio_keys]
    finally:
        env.close()


@functools.lru_cache(maxsize=None)
def _replay_module():
    """The reference replay script itself (`scripts/replay_demos_zarr.py`), loaded once
    (it defines absl flags)."""
    import importlib.util

    path = reference_code() / "scripts" / "replay_demos_zarr.py"
    spec = importlib.util.spec_from_file_location("replay_demos_zarr", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def replay(task: str, actions: np.ndarray, state0: np.ndarray, extend: int = 0, seed: int = 1):
    """Replays actions from state0 with the reference replay script's own function
    (restore on, randomization off, `--extend_steps` as given). Returns per step the
    state before the step, `succeed` and `terminated`."""
    module = _replay_module()
    module.FLAGS(["replay", "--norandomize", f"--extend_steps={extend}", "--restore_state"])
    config = CONFIG_MAPPING[task]()
    _succeed, trajectory = module._replay_single_demo(
        actions, state0, task, config, env_seed=seed, desc=task
    )
    state = np.stack([np.asarray(t["observations"]["state"]) for t in trajectory])
    succeed = np.array([bool(t["infos"].get("succeed", False)) for t in trajectory])
    terminated = np.array([bool(t["dones"]) for t in trajectory])
    return state, succeed, terminated


def record(task: str, episode: Path, out: Path) -> dict:
    """The reference's own recording of an episode's actions: its replay, written by the
    replay script's writer (`_write_demo_zarr_and_videos`: `replay.zarr` through the
    reference's `ZarrEpisodeStore`, with `state`, `action`, `action_rotvec`,
    `timestamp`), without videos (nothing is rendered here)."""
    module = _replay_module()
    actions, state0 = read_episode(episode)
    module.FLAGS(["replay", "--norandomize", "--extend_steps=0", "--restore_state"])
    config = CONFIG_MAPPING[task]()
    succeed, trajectory = module._replay_single_demo(actions, state0, task, config, env_seed=1, desc=task)
    for t in trajectory:
        t["observations"] = {"state": t["observations"]["state"]}
    folder = module._write_demo_zarr_and_videos(trajectory, task, 1, out, 30)
    succeeded = [bool(t["infos"].get("succeed", False)) for t in trajectory]
    return {
        "folder": folder,
        "succeed": bool(succeed),
        "first_success": _first(np.array(succeeded)),
        "arithmetic": reference_arithmetic.NAME,
    }


def read_episode(folder: Path):
    """The actions and state[0] of a raw episode (`replay.zarr`)."""
    import zarr

    root = zarr.open(str(folder / "replay.zarr"), mode="r")
    return np.asarray(root["data"]["action"]), np.asarray(root["data"]["state"][0]).ravel()


def _first(flags: np.ndarray):
    hits = np.flatnonzero(flags)
    return int(hits[0]) if hits.size else None


def nudged(actions: np.ndarray, metres: float) -> np.ndarray:
    """The actions with `metres` added to the x of every arm position target that is not
    a hold (all-zero pose): the reference's own sensitivity to a tiny change."""
    out = actions.copy()
    for arm in range(actions.shape[1] // 23):
        moving = np.any(actions[:, arm * 23 : arm * 23 + 7] != 0, axis=1)
        out[moving, arm * 23] += metres
    return out


def replay_job(job: dict, out_dir: Path, tag: str = "") -> dict:
    """One parity job under this process's arithmetic: the reference replay of a raw
    episode, plain and with each of the job's nudges; arrays to
    `out_dir/<name>[-<tag>].npz` (`state_k`, `succeed_k`, `terminated_k`), the runs'
    verdicts returned."""
    actions, state0 = read_episode(Path(job["episode"]))
    cap = job.get("step_cap")
    arrays = {}
    runs = []
    for k, metres in enumerate([0.0] + list(job.get("nudges", []))):
        acts = nudged(actions, metres) if metres else actions
        state, succeed, terminated = replay(job["task"], acts, state0, job.get("extend", 0))
        arrays[f"state_{k}"], arrays[f"succeed_{k}"] = state, succeed
        arrays[f"terminated_{k}"] = terminated
        runs.append(
            {
                "arithmetic": reference_arithmetic.NAME,
                "nudge": metres,
                "steps": int(len(state)),
                "first_success": _first(succeed),
                "first_failure": _first(failures(succeed, terminated, cap)),
            }
        )
    np.savez(_npz(out_dir, job["name"], tag), **arrays)
    return {"name": job["name"], "task": job["task"], "tag": tag, "runs": runs}


def _npz(out_dir: Path, name: str, tag: str) -> Path:
    return out_dir / (f"{name}-{tag}.npz" if tag else f"{name}.npz")


def summarize_job(job: dict, out_dir: Path, primary: str, members: list[str]) -> dict:
    """Compares the runs `replay_job` saved for one job: the primary run (`primary`'s
    plain replay) against the ensemble of the reference's own perturbations (the
    primary's nudged runs and each member tag's plain run, under other arithmetic), and
    our trajectory (`job["ours"]`) against the primary. The ensemble measures where the
    reference's own trajectory is chaotic: our state is compared with the primary's only
    until 10 steps before the first ensemble run departs from it by 1e-6 (the calm part)."""
    cap = job.get("step_cap")
    saved = {tag: np.load(_npz(out_dir, job["name"], tag)) for tag in [primary, *members]}
    runs = []
    for tag, arrays in saved.items():
        count = sum(1 for key in arrays.files if key.startswith("state_"))
        for k in range(count if tag == primary else 1):
            runs.append((tag, k, arrays))
    base = saved[primary]
    # Nothing after a failure compares: the reference's hanoi env freezes, then resets
    # itself 3 s of wall-clock time later (a teleoperation convenience).
    first_failure = _first(failures(base["succeed_0"], base["terminated_0"], cap))
    end = None if first_failure is None else first_failure + 1
    reference = base["state_0"][:end]
    blocks = state_blocks(job["task"])
    summary = {"name": job["name"], "task": job["task"], "blocks": blocks, "runs": []}
    departures = []
    for tag, k, arrays in runs:
        succeed, terminated = arrays[f"succeed_{k}"], arrays[f"terminated_{k}"]
        run = {
            "tag": tag,
            "nudge": float(job.get("nudges", [])[k - 1]) if k else 0.0,
            "first_success": _first(succeed),
            "first_failure": _first(failures(succeed, terminated, cap)),
        }
        if (tag, k) != (primary, 0):
            diff = compare(arrays[f"state_{k}"][:end], reference, blocks)
            run["departs"] = diff["first_step_over_tol"]
            run["max_diff"] = diff["max_diff"]
            if diff["first_step_over_tol"] is not None:
                departures.append(diff["first_step_over_tol"])
        summary["runs"].append(run)
    summary["self"] = {"max_diff": max((r.get("max_diff", 0.0) for r in summary["runs"]), default=0.0)}
    if job.get("ours"):
        ours = read_states(Path(job["ours"]))[:end]
        summary["ours"] = compare(ours, reference, blocks)
        # Until 10 steps before the first ensemble run departs from the primary by more
        # than 1e-6: the part of the trajectory that is not chaotic (a rounding
        # difference can set off the same contact event a step or two earlier).
        calm = len(ours) if not departures else max(0, min(departures) - CALM_MARGIN)
        summary["ours"]["max_diff_while_calm"] = compare(ours[:calm], reference[:calm], blocks)["max_diff"]
        summary["ours"]["calm_steps"] = int(min(calm, len(ours)))
    return summary


def failures(succeed: np.ndarray, terminated: np.ndarray, step_cap) -> np.ndarray:
    """Steps that end the episode without success before the step cap (the task's
    failure condition; the cap's own termination is not one)."""
    steps = np.arange(len(succeed))
    before_cap = steps + 1 < step_cap if step_cap else np.ones(len(succeed), dtype=bool)
    return terminated & ~succeed & before_cap


def read_states(folder: Path) -> np.ndarray:
    """The state array of a raw episode."""
    import zarr

    return np.asarray(zarr.open(str(folder / "replay.zarr"), "r")["data"]["state"])


def compare(other: np.ndarray, ref: np.ndarray, blocks, tol: float = 1e-6) -> dict:
    """How far `other` is from the reference's state trajectory over their common steps:
    the max |difference| per state block, and the first step where it exceeds `tol`."""
    n = min(len(other), len(ref))
    diff = np.abs(other[:n] - ref[:n])
    per_block, start = {}, 0
    for name, width in blocks:
        per_block[name] = float(diff[:, start : start + width].max(initial=0.0))
        start += width
    return {
        "steps": n,
        "max_diff": float(diff.max(initial=0.0)),
        "max_diff_per_block": per_block,
        "first_step_over_tol": _first(diff.max(axis=1) > tol),
    }


def _cli(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    r = sub.add_parser("replay", help="replay a raw episode with the reference replay")
    r.add_argument("--task", required=True)
    r.add_argument("--episode", type=Path, required=True)
    r.add_argument("--out", type=Path, required=True)
    r.add_argument("--extend", type=int, default=0)
    r.add_argument(
        "--nudge",
        type=float,
        default=0.0,
        help="add this many metres to every arm position target (sensitivity)",
    )
    rec = sub.add_parser("record", help="the reference's own recording of a raw episode's actions")
    rec.add_argument("--task", required=True)
    rec.add_argument("--episode", type=Path, required=True)
    rec.add_argument("--out", type=Path, required=True, help="folder for the recording's folder")
    b = sub.add_parser("batch", help="replay the jobs of a JSON list (name, task, episode, extend, nudges)")
    b.add_argument("--jobs", type=Path, required=True)
    b.add_argument("--out", type=Path, required=True, help="folder for <name>[-<tag>].npz")
    b.add_argument("--tag", default="", help="names this run's arrays (one per arithmetic)")
    s = sub.add_parser("summarize", help="compare the runs batch saved (primary, ensemble, ours)")
    s.add_argument("--jobs", type=Path, required=True)
    s.add_argument("--out", type=Path, required=True, help="the folder batch wrote to")
    s.add_argument("--primary", required=True, help="the tag of the primary runs")
    s.add_argument("--members", default="", help="tags whose plain run joins the ensemble")
    args = parser.parse_args(argv)
    if args.command == "record":
        print(json.dumps(record(args.task, args.episode, args.out)))
        return
    if args.command == "batch":
        jobs = json.loads(args.jobs.read_text())
        print(json.dumps([replay_job(job, args.out, args.tag) for job in jobs]))
        return
    if args.command == "summarize":
        jobs = json.loads(args.jobs.read_text())
        members = [m for m in args.members.split(",") if m]
        print(json.dumps([summarize_job(job, args.out, args.primary, members) for job in jobs]))
        return
    actions, state0 = read_episode(args.episode)
    if args.nudge:
        actions = nudged(actions, args.nudge)
    state, succeed, terminated = replay(args.task, actions, state0, args.extend)
    np.savez(args.out, state=state, succeed=succeed, terminated=terminated)
    print(
        json.dumps(
            {
                "arithmetic": reference_arithmetic.NAME,
                "steps": int(len(state)),
                "first_success": _first(succeed),
                "first_termination_without_success": _first(terminated & ~succeed),
                "blocks": state_blocks(args.task),
            }
        )
    )


if __name__ == "__main__":
    _cli()
