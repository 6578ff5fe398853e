"""The DexJoCo reference evaluation client, run as shipped (reference venv): its
`eval_dexjoco_openpi.main` with real EGL rendering and its videos, against a policy
server, for `scripts/bench-eval.sh`'s side-by-side throughput:

    python reference_eval_client.py --config CONFIG.yaml --port P --episodes N --out DIR [--no-sleep] [--step-cap N]

`--no-sleep` removes the environments' 30 Hz pacing sleep; `--step-cap N` ends each
episode after N steps (as `eval --step-cap`: the client's environment reports done), so
that a benchmark needs minutes, not hours, on a CPU. Without them the client runs
exactly as shipped. Prints {"episodes": N, "seconds": wall time, "steps": steps run} as JSON.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ["DEXJOCO_REFERENCE_RENDER"] = "1"
if "--no-sleep" not in sys.argv:
    os.environ["DEXJOCO_REFERENCE_SLEEP"] = "1"

import dexjoco_reference as ref  # noqa: E402  (pins the arithmetic, makes the scratch copy)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--config", type=Path, required=True)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--host", default="127.0.0.1")
    p.add_argument("--port", type=int, required=True)
    p.add_argument("--episodes", type=int, default=1)
    p.add_argument("--out", type=Path, required=True)
    p.add_argument("--no-sleep", action="store_true")
    p.add_argument("--step-cap", type=int)
    args = p.parse_args(argv)
    # The client package beside (after) the scratch copy of `dexjoco`, which shadows the
    # original one next to it.
    sys.path.append(str(ref.reference_code() / "dexjoco"))
    from dexjoco_openpi_client import dexjoco_openpi_env
    from dexjoco_openpi_client.eval_dexjoco_openpi import main as evaluate

    steps = count_steps(dexjoco_openpi_env.DexJoCoOpenPIEnv, args.step_cap)
    started = time.monotonic()
    evaluate(
        config=args.config,
        seed=args.seed,
        port=args.port,
        host=args.host,
        output=args.out,
        episodes=args.episodes,
    )
    print(json.dumps({"episodes": args.episodes, "seconds": time.monotonic() - started, "steps": steps[0]}))


def count_steps(env_class, cap):
    """Counts the steps the environments run (the reference's `env_step`, warm-up
    included) and, with a cap, reports done once an episode has run `cap` of them."""
    total = [0]
    step, reset = env_class.step, env_class.reset

    def counted_reset(self, *a, **k):
        self._bench_steps = 0
        return reset(self, *a, **k)

    def counted_step(self, *a, **k):
        out = step(self, *a, **k)
        self._bench_steps = getattr(self, "_bench_steps", 0) + 1
        total[0] += 1
        if cap is not None and self._bench_steps >= cap:
            self._done = True
        return out

    env_class.reset, env_class.step = counted_reset, counted_step
    return total


if __name__ == "__main__":
    main()
