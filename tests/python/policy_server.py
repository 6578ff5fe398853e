"""Policy servers for the `eval` tests, built on openpi's own websocket policy server
(`openpi/src/openpi/serving/websocket_policy_server.py` of the DexJoCo reference code,
imported in place from ../shared; reference venv, which has `openpi-client`):

    python policy_server.py --port P oracle --plans DIR [DIR ...] [--perturb A --log FILE]
                                            [--cut-after-first-subtask]
    python policy_server.py --port P hold
    python policy_server.py --port P record --out FILE.npz [--count N] [--close]
    python policy_server.py --port P misbehave --how {shape,nan,close,silent,error} [--after N]

- `oracle` answers each observation with the next 30 actions of the plan `scripted` made
  for the episode's reset: it finds the plan whose `state[0]` equals the observation's
  `dexjoco/initial_state` (eval --privileged-keys) and cuts its `action_rotvec` at
  `dexjoco/step` (the last action repeated past the plan's end). An episode without a plan
  is answered with the pose held. With `--perturb A` every chunk is moved off the plan by
  a small pattern of amplitude A that differs from chunk to chunk (positions and hands
  shifted, rotations turned by up to A rad), so that where chunks overlap the blend
  decides the executed action; `--log FILE` appends every answer (plan index, step, chunk)
  as a JSON line, for `reference_chunk_merge.py` to merge as the reference client does
  (with the observation's `environment_state` when it has one, eval --environment-state).
  With `--cut-after-first-subtask` each plan stops where its first subtask ended (the
  `plan.json` `scripted` writes beside it): the last action of that subtask is repeated
  from then on, so the episode completes its first subtask and no other.
- `hold` answers every observation with the pose held (any client, no privileged keys:
  `scripts/bench-eval.sh`'s policy, which runs every episode to its step cap).
- `record` keeps the first N observations it receives (every key) in FILE.npz and answers
  with the pose held.
- `misbehave` answers well N times, then: a chunk of the wrong width (`shape`), a chunk
  with a NaN (`nan`), closes the connection (`close`), never answers (`silent`) or fails in
  the policy (`error`: openpi's server sends the traceback as text and closes).

It prints `listening <port>` on stdout once the socket is open.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation as R

HORIZON = 30


def _openpi_server():
    """openpi's WebsocketPolicyServer, from the reference code beside the checkout."""
    code = Path(os.environ.get("DEXJOCO_REFERENCE_CODE", Path(__file__).resolve().parents[3] / "shared/third_party/dexjoco-8d23b0f"))
    src = code / "openpi" / "src"
    if not (src / "openpi" / "serving" / "websocket_policy_server.py").is_file():
        sys.exit(f"error: openpi's server not found under {src}: put the DexJoCo reference code there or set $DEXJOCO_REFERENCE_CODE")
    sys.path.insert(0, str(src))
    from openpi.serving import websocket_policy_server

    return websocket_policy_server.WebsocketPolicyServer


def hold(state: np.ndarray) -> np.ndarray:
    """The action (policy layout) that holds the pose of a proprio state, as the reference
    client's stay(): per arm TCP xyz and rotation vector, then the hands' joints."""
    arms = 2 if len(state) >= 46 and np.any(state[23:46]) else 1
    out = []
    for a in range(arms):
        p = state[a * 7 : a * 7 + 7]
        out += [p[:3], R.from_quat(p[3:7], scalar_first=True).as_rotvec()]
        out.append(state[arms * 7 + a * 16 : arms * 7 + a * 16 + 16])
    return np.concatenate(out)


def held_chunk(obs) -> np.ndarray:
    """A whole chunk that holds the observation's pose."""
    return np.tile(hold(np.asarray(obs["state"])), (HORIZON, 1))


def _chunk_of(rows: np.ndarray, step: int) -> np.ndarray:
    idx = np.minimum(np.arange(step, step + HORIZON), len(rows) - 1)
    return rows[idx]


def perturbed(chunk: np.ndarray, step: int, amplitude: float) -> np.ndarray:
    """`chunk` moved off by a pattern of `amplitude` unique to `step`: per arm, the
    position and hand joints shifted, the rotation vector turned about a varying axis."""
    out = np.array(chunk, dtype=np.float64, copy=True)
    rows, width = out.shape
    k = np.arange(rows)[:, None]
    j = np.arange(width)[None, :]
    out += amplitude * np.sin(0.37 * step + 0.29 * k + 1.3 * j)
    per_arm = 22
    for arm in range(width // per_arm):
        r = slice(arm * per_arm + 3, arm * per_arm + 6)
        axis = np.stack([np.sin(0.5 * step + 0.2 * k[:, 0]), np.cos(0.3 * step + 0.1 * k[:, 0]), np.full(rows, 0.5)], axis=1)
        turn = amplitude * axis / np.linalg.norm(axis, axis=1, keepdims=True)
        out[:, r] = (R.from_rotvec(turn) * R.from_rotvec(chunk[:, r])).as_rotvec()
    return out


class Oracle:
    """Answers with the plan of the episode's reset."""

    def __init__(self, dirs, perturb: float = 0.0, log: Path | None = None, cut: bool = False):
        import zarr

        self.perturb, self.log = perturb, log
        self.plans = []
        for d in dirs:
            for z in sorted(Path(d).rglob("replay.zarr")):
                root = zarr.open(str(z), "r")
                data = root["data"]
                rows = np.asarray(data["action_rotvec"])
                if cut:
                    first = json.loads((z.parent / "plan.json").read_text())["subtasks"][0]
                    rows = rows[: first["end"] + 1]
                self.plans.append((np.asarray(data["state"][0]), rows))

    def infer(self, obs):
        s0 = np.asarray(obs["dexjoco/initial_state"])
        step = int(obs["dexjoco/step"])
        for index, (state0, rows) in enumerate(self.plans):
            if state0.shape == s0.shape and np.max(np.abs(state0 - s0)) <= 1e-12:
                chunk = _chunk_of(rows, step)
                if self.perturb:
                    chunk = perturbed(chunk, step, self.perturb)
                if self.log is not None:
                    line = {"plan": index, "step": step, "chunk": chunk.tolist()}
                    if "environment_state" in obs:
                        # repr of a float64 round-trips exactly
                        line["environment_state"] = np.asarray(obs["environment_state"], dtype=np.float64).tolist()
                    with open(self.log, "a") as f:
                        f.write(json.dumps(line) + "\n")
                return {"actions": chunk}
        return {"actions": held_chunk(obs)}


class Hold:
    """Answers with the observation's pose held."""

    def infer(self, obs):
        return {"actions": held_chunk(obs)}


class Recorder:
    """Keeps the first observations it receives; with `close`, ends the process at the
    next one (the client's episode goes no further)."""

    def __init__(self, out: Path, count: int, close: bool):
        self.out, self.count, self.seen, self.close = out, count, [], close

    def infer(self, obs):
        if self.close and len(self.seen) >= self.count:
            os._exit(0)
        if len(self.seen) < self.count:
            self.seen.append(obs)
            if len(self.seen) == self.count:
                arrays = {}
                for i, o in enumerate(self.seen):
                    for k, v in o.items():
                        name = f"{i}/{k}"
                        arrays[name] = np.asarray(v) if not isinstance(v, str) else np.array(v)
                tmp = self.out.with_suffix(".tmp.npz")
                np.savez(tmp, **arrays)
                os.replace(tmp, self.out)
        return {"actions": held_chunk(obs)}


class Misbehave:
    """Answers well `after` times, then misbehaves as asked."""

    def __init__(self, how: str, after: int):
        self.how, self.after, self.n = how, after, 0

    def infer(self, obs):
        self.n += 1
        good = held_chunk(obs)
        if self.n <= self.after:
            return {"actions": good}
        if self.how == "shape":
            return {"actions": good[:, :-1]}
        if self.how == "nan":
            good[3, 4] = np.nan
            return {"actions": good}
        if self.how == "close":
            os._exit(0)  # the connection drops mid-episode
        if self.how == "silent":
            time.sleep(3600)
        raise RuntimeError("the policy failed on purpose (misbehave --how error)")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--host", default="127.0.0.1")
    sub = p.add_subparsers(dest="policy", required=True)
    o = sub.add_parser("oracle")
    o.add_argument("--plans", nargs="+", required=True)
    o.add_argument("--perturb", type=float, default=0.0, help="move each chunk off the plan by this much")
    o.add_argument("--log", type=Path, help="append every answer to this JSON-lines file")
    o.add_argument("--cut-after-first-subtask", action="store_true", help="stop each plan where its first subtask ended")
    sub.add_parser("hold")
    r = sub.add_parser("record")
    r.add_argument("--out", type=Path, required=True)
    r.add_argument("--count", type=int, default=1)
    r.add_argument("--close", action="store_true", help="end at the observation after the last kept")
    m = sub.add_parser("misbehave")
    m.add_argument("--how", choices=["shape", "nan", "close", "silent", "error"], required=True)
    m.add_argument("--after", type=int, default=0)
    args = p.parse_args(argv)
    if args.policy == "oracle":
        policy, meta = Oracle(args.plans, args.perturb, args.log, args.cut_after_first_subtask), {"policy": "oracle"}
    elif args.policy == "hold":
        policy, meta = Hold(), {"policy": "hold"}
    elif args.policy == "record":
        policy, meta = Recorder(args.out, args.count, args.close), {"policy": "record"}
    else:
        policy, meta = Misbehave(args.how, args.after), {"policy": f"misbehave-{args.how}"}
    server = _openpi_server()(policy, host=args.host, port=args.port, metadata=meta)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    _announce(args.host, args.port)
    threading.Event().wait()


def _announce(host: str, port: int):
    """Prints `listening <port>` once the port accepts connections."""
    import socket

    for _ in range(600):
        try:
            with socket.create_connection((host, port), timeout=0.2):
                print(f"listening {port}", flush=True)
                return
        except OSError:
            time.sleep(0.05)
    sys.exit(f"error: the server did not open {host}:{port}")


if __name__ == "__main__":
    main()
