#!/usr/bin/env python3
"""A state-based behaviour-cloning policy for DexJoCo, trained on a LeRobot v3.0 dataset and
served to ``dexjoco-data eval`` through openpi's websocket protocol.

The cheapest policy that can say whether a dataset teaches: robomimic's low-dimensional
BC (an MLP of two 1,024-unit layers, Adam 1e-4, batch 100) in plain PyTorch, from the
proprioception (``observation.state``) and the objects' state (``observation.environment_state``,
``convert --environment-state``) to the next ``--horizon`` actions (``action``, per arm xyz,
rotation vector, 16 hand targets: what eval executes), inputs and outputs normalized by the
dataset's mean and std. Every rotation goes through the network as Diffusion Policy's
continuous 6D (see ``Layout``): a gripper pointing down sits where a rotation vector jumps
from +pi to -pi, and regressed as numbers the two average to a wrong orientation. Trained on
the CPU in minutes.

    # train: writes OUT/model.pt and OUT/curve.csv (step, loss, held-out loss)
    python examples/bc_policy.py train DATASET OUT [--steps 20000] [--horizon 10] [--seed 0]

    # serve it (eval must send the environment state: --environment-state)
    python examples/bc_policy.py serve OUT/model.pt --port 8000
    dexjoco-data eval --task click_mouse --environment-state --no-cameras --no-videos \\
        --host 127.0.0.1 --port 8000 --episodes 50

The server is stateless (each chunk from its observation alone), so ``eval -j N`` may share
it. openpi's websocket server is imported from openpi's source tree (``--openpi-src``, by
default the reference code beside this checkout); it needs ``openpi-client``, ``websockets``
and ``msgpack`` (the test venv has them).
"""

from __future__ import annotations

import argparse
import csv
import json
import logging
import sys
import time
from pathlib import Path

import numpy as np

LOG = logging.getLogger("bc_policy")
REPO_ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OPENPI_SRC = REPO_ROOT.parent / "shared" / "third_party" / "dexjoco-8d23b0f" / "openpi" / "src"
STATE, ENV, ACTION = "observation.state", "observation.environment_state", "action"


def env_names(root: Path) -> list[str]:
    info = json.loads((root / "meta" / "info.json").read_text())
    return list(info["features"][ENV]["names"])


def read_dataset(root: Path) -> dict[str, np.ndarray]:
    """Every frame's state, environment state, action and episode index (float64)."""
    import pyarrow.parquet as pq

    info = json.loads((root / "meta" / "info.json").read_text())
    for key in (STATE, ENV, ACTION):
        if key not in info["features"]:
            raise SystemExit(f"{root}: no {key} feature (convert with --environment-state)")
    files = sorted((root / "data").rglob("*.parquet"))
    cols: dict[str, list[np.ndarray]] = {k: [] for k in (STATE, ENV, ACTION, "episode_index")}
    for f in files:
        t = pq.read_table(f, columns=list(cols))
        for k in cols:
            v = t.column(k).to_pylist()
            cols[k].append(np.asarray(v, dtype=np.float64))
    out = {k: np.concatenate(v) for k, v in cols.items()}
    out["episode_index"] = out["episode_index"].reshape(-1).astype(np.int64)
    return out


def rot6d_from_matrix(m: np.ndarray) -> np.ndarray:
    """Diffusion Policy's (pytorch3d's) 6D rotation: the matrix's first two rows."""
    return m[..., :2, :].reshape(*m.shape[:-2], 6)


def matrix_from_rot6d(d6: np.ndarray) -> np.ndarray:
    """pytorch3d's ``rotation_6d_to_matrix``: Gram-Schmidt on the two rows."""
    a1, a2 = d6[..., :3], d6[..., 3:]
    b1 = a1 / np.linalg.norm(a1, axis=-1, keepdims=True)
    b2 = a2 - (b1 * a2).sum(-1, keepdims=True) * b1
    b2 = b2 / np.linalg.norm(b2, axis=-1, keepdims=True)
    return np.stack([b1, b2, np.cross(b1, b2)], axis=-2)


class Layout:
    """How the network sees the data: every rotation as Diffusion Policy's continuous 6D.

    A rotation vector jumps between +pi and -pi about an axis as an orientation crosses a
    half turn (a gripper pointing down is right there), and a quaternion and its negative
    are one rotation: regressed as numbers, both average two equal targets into a third,
    wrong one. So the proprioception's TCP quaternions, the environment state's object
    quaternions and the actions' rotation vectors go in and out as 6D (the first two rows of
    the rotation matrix), positions and hands as they are.
    """

    def __init__(self, state_dim: int, env_names: list[str], action_dim: int):
        from scipy.spatial.transform import Rotation as R

        self.R = R
        self.arms = action_dim // 22
        self.state_dim, self.action_dim = state_dim, action_dim
        # Environment columns: each "<object>.pose[0..6]" run is a position + quaternion.
        self.env_quats = []
        for i, name in enumerate(env_names):
            if name.endswith(".pose[3]") and i + 3 < len(env_names) and env_names[i + 3].endswith(".pose[6]"):
                self.env_quats.append(i)

    def _quats_to_6d(self, x: np.ndarray, starts: list[int]) -> np.ndarray:
        parts, at = [], 0
        for q in starts:
            parts.append(x[:, at:q])
            m = self.R.from_quat(x[:, q : q + 4], scalar_first=True).as_matrix()
            parts.append(rot6d_from_matrix(m))
            at = q + 4
        parts.append(x[:, at:])
        return np.concatenate(parts, axis=1)

    def inputs(self, state: np.ndarray, env: np.ndarray) -> np.ndarray:
        """The network's input rows from proprioception and environment state rows."""
        tcp = [a * 7 + 3 for a in range(self.arms)]  # per arm xyz, quaternion wxyz, then the hands
        return np.concatenate([self._quats_to_6d(state, tcp), self._quats_to_6d(env, self.env_quats)], axis=1)

    def actions_to_net(self, a: np.ndarray) -> np.ndarray:
        """(n, action_dim) rotation-vector actions -> (n, 25 per arm)."""
        out = []
        for arm in range(self.arms):
            o = arm * 22
            m = self.R.from_rotvec(a[:, o + 3 : o + 6]).as_matrix()
            out += [a[:, o : o + 3], rot6d_from_matrix(m), a[:, o + 6 : o + 22]]
        return np.concatenate(out, axis=1)

    def actions_from_net(self, y: np.ndarray) -> np.ndarray:
        """(n, 25 per arm) -> (n, action_dim) rotation-vector actions, as eval executes them."""
        out = []
        for arm in range(self.arms):
            o = arm * 25
            m = matrix_from_rot6d(y[:, o + 3 : o + 9])
            out += [y[:, o : o + 3], self.R.from_matrix(m).as_rotvec(), y[:, o + 9 : o + 25]]
        return np.concatenate(out, axis=1)


def chunks(actions: np.ndarray, episodes: np.ndarray, horizon: int) -> np.ndarray:
    """Per frame, its next ``horizon`` actions within its episode (the last one repeated past the end)."""
    n, d = actions.shape
    out = np.empty((n, horizon, d))
    ends = np.zeros(n, dtype=np.int64)
    for e in np.unique(episodes):
        idx = np.nonzero(episodes == e)[0]
        ends[idx] = idx[-1]
    for k in range(horizon):
        out[:, k] = actions[np.minimum(np.arange(n) + k, ends)]
    return out


class Normalizer:
    def __init__(self, x: np.ndarray):
        self.mean = x.mean(axis=0)
        self.std = np.maximum(x.std(axis=0), 1e-6)

    def __call__(self, x):
        return (x - self.mean) / self.std

    def undo(self, x):
        return x * self.std + self.mean

    def to_dict(self):
        return {"mean": self.mean.tolist(), "std": self.std.tolist()}

    @classmethod
    def from_dict(cls, d):
        n = cls.__new__(cls)
        n.mean, n.std = np.asarray(d["mean"]), np.asarray(d["std"])
        return n


def mlp(inputs: int, outputs: int, hidden: int, layers: int):
    import torch.nn as nn

    mods, width = [], inputs
    for _ in range(layers):
        mods += [nn.Linear(width, hidden), nn.ReLU()]
        width = hidden
    mods.append(nn.Linear(width, outputs))
    return nn.Sequential(*mods)


def train(args) -> None:
    import torch

    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    torch.set_num_threads(args.threads)
    d = read_dataset(Path(args.dataset))
    names = env_names(Path(args.dataset))
    layout = Layout(d[STATE].shape[1], names, d[ACTION].shape[1])
    x = layout.inputs(d[STATE], d[ENV])
    y = chunks(layout.actions_to_net(d[ACTION]), d["episode_index"], args.horizon)
    n, action_dim = len(x), y.shape[2]
    y = y.reshape(n, -1)
    episodes = np.unique(d["episode_index"])
    held = set(rng.choice(episodes, size=max(1, len(episodes) // 20), replace=False).tolist()) if len(episodes) > 1 else set()
    is_held = np.isin(d["episode_index"], list(held))
    xn, yn = Normalizer(x[~is_held]), Normalizer(y[~is_held])
    xt = torch.tensor(xn(x), dtype=torch.float32)
    yt = torch.tensor(yn(y), dtype=torch.float32)
    train_idx, held_idx = np.nonzero(~is_held)[0], np.nonzero(is_held)[0]
    model = mlp(x.shape[1], y.shape[1], args.hidden, args.layers)
    opt = torch.optim.Adam(model.parameters(), lr=args.lr)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    curve = [("step", "loss", "held_out_loss", "seconds")]
    started, running = time.time(), 0.0
    LOG.info("%d frames (%d episodes, %d held out), input %d, output %d x %d", n, len(episodes), len(held), x.shape[1], args.horizon, action_dim)
    for step in range(1, args.steps + 1):
        b = torch.as_tensor(rng.choice(train_idx, size=args.batch))
        loss = torch.nn.functional.mse_loss(model(xt[b]), yt[b])
        opt.zero_grad()
        loss.backward()
        opt.step()
        running += loss.item()
        if step % args.log_every == 0 or step == args.steps:
            held_loss = float("nan")
            if len(held_idx):
                with torch.no_grad():
                    h = torch.as_tensor(held_idx[: 20000])
                    held_loss = torch.nn.functional.mse_loss(model(xt[h]), yt[h]).item()
            curve.append((step, running / args.log_every, held_loss, round(time.time() - started, 1)))
            LOG.info("step %d loss %.5f held-out %.5f (%.0f s)", step, running / args.log_every, held_loss, time.time() - started)
            running = 0.0
    torch.save(
        {
            "model": model.state_dict(),
            "inputs": x.shape[1],
            "state_dim": d[STATE].shape[1],
            "env_dim": d[ENV].shape[1],
            "env_names": names,
            "dataset_action_dim": d[ACTION].shape[1],
            "horizon": args.horizon,
            "action_dim": action_dim,
            "hidden": args.hidden,
            "layers": args.layers,
            "x_norm": xn.to_dict(),
            "y_norm": yn.to_dict(),
            "dataset": str(args.dataset),
            "frames": n,
        },
        out / "model.pt",
    )
    with open(out / "curve.csv", "w", newline="") as f:
        csv.writer(f).writerows(curve)
    print(json.dumps({"frames": n, "episodes": len(episodes), "final_loss": curve[-1][1], "held_out_loss": curve[-1][2], "seconds": curve[-1][3]}))


class BCPolicy:
    """The trained MLP behind openpi's ``infer(obs) -> {"actions": (horizon, action_dim)}``."""

    def __init__(self, checkpoint: Path):
        import torch

        self._torch = torch
        c = torch.load(checkpoint, weights_only=False)
        self.model = mlp(c["inputs"], c["horizon"] * c["action_dim"], c["hidden"], c["layers"])
        self.model.load_state_dict(c["model"])
        self.model.eval()
        self.c = c
        self.xn, self.yn = Normalizer.from_dict(c["x_norm"]), Normalizer.from_dict(c["y_norm"])
        self.layout = Layout(c["state_dim"], c["env_names"], c["dataset_action_dim"])

    def infer(self, obs: dict) -> dict:
        if "environment_state" not in obs:
            raise ValueError("no environment_state in the observation: run eval with --environment-state")
        state = np.asarray(obs["state"], dtype=np.float64)[None, : self.c["state_dim"]]
        env = np.asarray(obs["environment_state"], dtype=np.float64)[None]
        x = self.layout.inputs(state, env)
        with self._torch.no_grad():
            y = self.model(self._torch.tensor(self.xn(x), dtype=self._torch.float32)).numpy()
        y = self.yn.undo(y.astype(np.float64)).reshape(self.c["horizon"], self.c["action_dim"])
        return {"actions": self.layout.actions_from_net(y)}

    @property
    def metadata(self) -> dict:
        return {"policy": "bc_mlp", "horizon": self.c["horizon"], "frames": self.c["frames"]}


def serve(args) -> None:
    import torch

    torch.set_num_threads(1)
    sys.path.insert(0, str(Path(args.openpi_src)))
    from openpi.serving import websocket_policy_server  # noqa: PLC0415

    policy = BCPolicy(Path(args.checkpoint))
    LOG.info("serving %s on %s:%d", args.checkpoint, args.host, args.port)
    server = websocket_policy_server.WebsocketPolicyServer(policy=policy, host=args.host, port=args.port, metadata=policy.metadata)
    server.serve_forever()


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(message)s")
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", required=True)
    t = sub.add_parser("train", help="train on a LeRobot v3.0 dataset")
    t.add_argument("dataset")
    t.add_argument("out")
    t.add_argument("--steps", type=int, default=20000)
    t.add_argument("--batch", type=int, default=100)
    t.add_argument("--lr", type=float, default=1e-4)
    t.add_argument("--hidden", type=int, default=1024)
    t.add_argument("--layers", type=int, default=2)
    t.add_argument("--horizon", type=int, default=10)
    t.add_argument("--seed", type=int, default=0)
    t.add_argument("--threads", type=int, default=2)
    t.add_argument("--log-every", type=int, default=500)
    s = sub.add_parser("serve", help="serve a trained policy to dexjoco-data eval")
    s.add_argument("checkpoint")
    s.add_argument("--host", default="127.0.0.1")
    s.add_argument("--port", type=int, default=8000)
    s.add_argument("--openpi-src", default=str(DEFAULT_OPENPI_SRC))
    args = p.parse_args()
    (train if args.command == "train" else serve)(args)


if __name__ == "__main__":
    main()
