"""Computes normalization statistics with lerobot's own code
(lerobot.datasets.compute_stats) on the arrays in a JSON file and prints them as JSON.

input: {"episodes": [[[...row...], ...], ...], "images": {"path": raw uint8 file,
        "frames": N, "height": H, "width": W}}
output: {"episodes": [stats...], "aggregate": stats, "image": stats}
"""
import json
import sys

import numpy as np
from lerobot.datasets.compute_stats import (
    aggregate_stats,
    auto_downsample_height_width,
    get_feature_stats,
    sample_indices,
)


def plain(stats):
    return {k: np.asarray(v, dtype=np.float64).reshape(-1).tolist() for k, v in stats.items()}


spec = json.load(open(sys.argv[1]))
episodes = []
for rows in spec["episodes"]:
    arr = np.asarray(rows, dtype=np.float32)
    episodes.append({"x": get_feature_stats(arr, axis=0, keepdims=False)})
agg = aggregate_stats(episodes)["x"]
out = {"episodes": [plain(e["x"]) for e in episodes], "aggregate": plain(agg)}
# The exact population std (float64), which ours should equal to rounding.
for rows, e in zip(spec["episodes"], out["episodes"]):
    e["std64"] = np.std(np.asarray(rows, dtype=np.float32).astype(np.float64), axis=0).tolist()
im = spec.get("images")
if im:
    raw = np.fromfile(im["path"], dtype=np.uint8).reshape(im["frames"], im["height"], im["width"], 3)
    idx = sample_indices(im["frames"])
    chw = np.stack([auto_downsample_height_width(raw[i].transpose(2, 0, 1)) for i in idx])
    s = get_feature_stats(chw, axis=(0, 2, 3), keepdims=True)
    s = {k: v if k == "count" else np.squeeze(v / 255.0, axis=0) for k, v in s.items()}
    out["image"] = plain(s)
    flat = chw.transpose(0, 2, 3, 1).reshape(-1, 3).astype(np.float64)
    out["image"]["std64"] = (flat.std(axis=0) / 255.0).tolist()
    out["image_samples"] = idx
print(json.dumps(out))
