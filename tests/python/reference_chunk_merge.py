"""Merges the chunks a policy server answered (`policy_server.py oracle --log`) with the
DexJoCo reference client's own buffer code (`receive_actions` of
`dexjoco_openpi_client/eval_dexjoco_openpi.py`: alignment to the observation's timestamp,
expiry, blending with its weights and SciPy's geodesic rotation interpolation), each chunk
arriving `--latency` steps after the observation it answers, and compares the actions it
executes with the ones `eval` executed (its rollout's `action_rotvec`):

    python reference_chunk_merge.py --log LOG.jsonl --rollout EPISODE/replay.zarr --latency K

Prints JSON: the steps compared, the largest difference (metres, hand radians, and the
angle between rotations), the steps the reference holds the pose (no action buffered)
and the chunks merged.
"""

from __future__ import annotations

import argparse
import json
import queue
import sys
from collections import deque
from pathlib import Path

import dexjoco_reference as ref  # pins the arithmetic, makes the scratch copy

import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation as R  # noqa: E402


def difference(a: np.ndarray, b: np.ndarray) -> float:
    """The largest difference of two actions: positions and hand joints value by value,
    each arm's rotation as the angle between the two (a rotation vector near pi and its
    antipode are one rotation)."""
    worst = 0.0
    for arm in range(len(a) // 22):
        base = arm * 22
        rest = np.r_[base : base + 3, base + 6 : base + 22]
        worst = max(worst, float(np.max(np.abs(a[rest] - b[rest]))))
        turn = R.from_rotvec(a[base + 3 : base + 6]).inv() * R.from_rotvec(b[base + 3 : base + 6])
        worst = max(worst, float(turn.magnitude()))
    return worst


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--log", type=Path, required=True)
    p.add_argument("--rollout", type=Path, required=True)
    p.add_argument("--latency", type=int, required=True)
    p.add_argument("--warmup", type=int, default=0, help="rollout rows before timestamp 0")
    args = p.parse_args(argv)
    sys.path.append(str(ref.reference_code() / "dexjoco"))
    from dexjoco_openpi_client.eval_dexjoco_openpi import ActionChunk, receive_actions

    import zarr

    executed = np.asarray(zarr.open(str(args.rollout), "r")["data"]["action_rotvec"])[args.warmup :]
    answers = {}
    for line in args.log.read_text().splitlines():
        entry = json.loads(line)
        answers[entry["step"]] = np.asarray(entry["chunk"], dtype=np.float64)
    dual = executed.shape[1] == 44

    arriving = queue.Queue()
    buffer = deque()
    held, compared, worst, merged = [], 0, 0.0, 0
    for now in range(len(executed)):
        asked = now - args.latency
        if asked in answers:
            arriving.put(ActionChunk(action=answers[asked], timestamp=asked))
            merged += 1
        receive_actions(arriving, buffer, now, dual)
        if buffer:
            worst = max(worst, difference(buffer.popleft().action, executed[now]))
            compared += 1
        else:
            held.append(now)
    print(json.dumps({"compared": compared, "max_difference": worst, "held": held, "merged": merged, "answers": len(answers)}))


if __name__ == "__main__":
    main()
