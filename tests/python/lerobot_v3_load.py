"""Loads a LeRobot v3.0 dataset with lerobot's own reader (offline, root=) and prints,
as JSON, every item's values, task text and the mean RGB of each camera frame.

usage: lerobot_v3_load.py ROOT BACKEND   (BACKEND: pyav or torchcodec)
"""
import json
import os
import sys

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

from lerobot.datasets.lerobot_dataset import LeRobotDataset  # noqa: E402

root, backend = sys.argv[1], sys.argv[2]
ds = LeRobotDataset("local/dexjoco-test", root=root, video_backend=backend)
items = []
for i in range(len(ds)):
    it = ds[i]
    row = {
        "index": int(it["index"]),
        "episode_index": int(it["episode_index"]),
        "frame_index": int(it["frame_index"]),
        "timestamp": float(it["timestamp"]),
        "task": it["task"],
        "task_index": int(it["task_index"]),
        "action": [float(x) for x in it["action"]],
        "state": [float(x) for x in it["observation.state"]],
        "images": {},
    }
    for key in ds.meta.camera_keys:
        img = it[key]  # C, H, W float in [0, 1]
        row["images"][key] = [float(img[c].mean()) * 255.0 for c in range(img.shape[0])]
    items.append(row)
print(json.dumps({
    "len": len(ds),
    "num_episodes": ds.num_episodes,
    "fps": ds.fps,
    "camera_keys": list(ds.meta.camera_keys),
    "stats_keys": sorted(ds.meta.stats.keys()),
    "q01_action": [float(x) for x in ds.meta.stats["action"]["q01"]],
    "items": items,
}))
