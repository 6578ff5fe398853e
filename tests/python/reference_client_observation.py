"""The DexJoCo reference client's first observation, sent to a policy server (reference
venv; `tests/eval_cli.rs` runs it beside `dexjoco-data eval` to compare what both send):

    python reference_client_observation.py --config CONFIG.yaml --seed S --port P --state-out STATE.json

Runs the reference client's own code headless: `dexjoco_openpi_client/dexjoco_openpi_env.py`'s
`DexJoCoOpenPIEnv` (the reference environment with its own EGL renderer, as
`eval_dexjoco_openpi.py` creates it, global RNGs seeded as its `_set_seed`), reset, and its
observation sent by openpi-client's `WebsocketClientPolicy` (the protocol the reference
client uses). Writes the full DexJoCo state of the reset to STATE.json as
`{"initial_states": [[...]]}`, the form `dexjoco-data eval --resets-from` takes, so that our
client starts from the same scene state.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import random
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ["DEXJOCO_REFERENCE_RENDER"] = "1"

import dexjoco_reference as ref  # noqa: E402  (pins the arithmetic, makes the scratch copy)

import numpy as np  # noqa: E402
import yaml  # noqa: E402


def _client_env_module():
    """`dexjoco_openpi_env.py` of the reference code, loaded from its file (its package's
    siblings would shadow the scratch copy of `dexjoco`)."""
    path = ref.reference_code() / "dexjoco" / "dexjoco_openpi_client" / "dexjoco_openpi_env.py"
    spec = importlib.util.spec_from_file_location("dexjoco_openpi_env", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--config", type=Path, required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--state-out", type=Path, required=True)
    args = p.parse_args(argv)
    cfg = yaml.safe_load(args.config.read_text())
    # eval_dexjoco_openpi.main's _set_seed.
    np.random.seed(args.seed)
    random.seed(args.seed)
    env = _client_env_module().DexJoCoOpenPIEnv(
        env_name=cfg["env_name"],
        camera_mapping=cfg["camera_mapping"],
        seed=args.seed,
        rand_full=False,
        randomize_dynamics=False,
        dual_arm=cfg["robot_type"] == "dual_arm",
        prompt=cfg["prompt"],
        render_mode="rgb_array",
        pad_state_dim46=False,
        password=cfg.get("password"),
    )
    env.start()
    seen = {}
    process = env._process_obs

    def keep(env_obs):
        seen["state"] = np.asarray(env_obs["state"], dtype=np.float64)
        return process(env_obs)

    env._process_obs = keep
    env.reset()
    args.state_out.write_text(json.dumps({"initial_states": [seen["state"].tolist()]}))
    from openpi_client import websocket_client_policy

    client = websocket_client_policy.WebsocketClientPolicy(host=args.host, port=args.port)
    client.infer(env.get_obs())
    env.close()


if __name__ == "__main__":
    main()
