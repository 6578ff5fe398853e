"""Reads each frame's running subtask back from converted datasets, as their users read
it, and prints JSON {"v3": [...], "v21": [...], "dp": [...]} (one text per frame, in
dataset order; null where none), and "task_aug": each v3 episode's distinct `task_aug`
texts, in row order:

- LeRobot v3.0 through lerobot 0.6.1's own API: `LeRobotDataset` items carry
  `language_persistent`, resolved at the item's timestamp by lerobot's
  `language_render.active_at(style="subtask")`;
- LeRobot v2.1: the `subtask_index` column of every episode's parquet, into
  `meta/subtasks.jsonl`;
- Diffusion Policy: `data/subtask_index` of the store opened with zarr, into its
  `.zattrs` `subtasks`.

    python lerobot_subtasks.py V3_ROOT V21_ROOT DP_ROOT
"""

import json
import sys
from pathlib import Path

import numpy as np


def v3(root):
    from lerobot.datasets.language_render import active_at
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    ds = LeRobotDataset("local/subtasks", root=root)
    assert ds.meta.features["language_persistent"]["dtype"] == "language"
    out, aug = [], {}
    for i in range(len(ds)):
        item = ds[i]
        rows = item["language_persistent"]
        row = active_at(float(item["timestamp"]), persistent=rows, style="subtask")
        assert item["language_events"] == [], item["language_events"]
        out.append(row["content"] if row else None)
        texts = [r["content"] for r in rows if r["style"] == "task_aug" and r["role"] == "user"]
        aug.setdefault(int(item["episode_index"]), list(dict.fromkeys(texts)))
    return out, [aug[e] for e in sorted(aug)]


def v21(root):
    import pyarrow.parquet as pq

    root = Path(root)
    texts = [json.loads(line)["subtask"] for line in (root / "meta/subtasks.jsonl").read_text().splitlines()]
    out = []
    for f in sorted((root / "data").rglob("*.parquet")):
        for i in pq.read_table(f)["subtask_index"].to_pylist():
            out.append(texts[i] if i >= 0 else None)
    return out


def dp(root):
    import zarr

    store = zarr.open(str(Path(root) / "replay_buffer.zarr"), "r")
    arr = store["data/subtask_index"]
    texts = arr.attrs["subtasks"]
    return [texts[i] if i >= 0 else None for i in np.asarray(arr[:]).tolist()]


if __name__ == "__main__":
    a, b, c = sys.argv[1:4]
    frames, aug = v3(a)
    print(json.dumps({"v3": frames, "task_aug": aug, "v21": v21(b), "dp": dp(c)}))
