"""The DexJoCo reference evaluation client, run as shipped (reference venv): its
`eval_dexjoco_openpi.main` with real EGL rendering and its videos, against a policy
server, for `scripts/bench-eval.sh`'s side-by-side throughput:

    python reference_eval_client.py --config CONFIG.yaml --port P --episodes N --out DIR [--no-sleep]

`--no-sleep` removes the environments' 30 Hz pacing sleep (the only change); without it
the client runs exactly as shipped. Prints {"episodes": N, "seconds": wall time} as JSON.
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
    args = p.parse_args(argv)
    # The client package beside (after) the scratch copy of `dexjoco`, which shadows the
    # original one next to it.
    sys.path.append(str(ref.reference_code() / "dexjoco"))
    from dexjoco_openpi_client.eval_dexjoco_openpi import main as evaluate

    started = time.monotonic()
    evaluate(
        config=args.config,
        seed=args.seed,
        port=args.port,
        host=args.host,
        output=args.out,
        episodes=args.episodes,
    )
    print(json.dumps({"episodes": args.episodes, "seconds": time.monotonic() - started}))


if __name__ == "__main__":
    main()
