"""Writes a small LeRobot v3.0 dataset with lerobot's own writer (LeRobotDataset.create /
add_frame / save_episode / finalize), as a dataset downloaded from the Hub is made:
EPISODES episodes of two tasks, lengths 20 + 7 * (i % 4), a 6-wide action, a 4-wide
state and one 32x32 camera whose frames encode (episode, frame) as colours.

usage: lerobot_small_dataset.py OUT_ROOT EPISODES
"""
import os
import sys

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

import numpy as np  # noqa: E402
from lerobot.datasets.lerobot_dataset import LeRobotDataset  # noqa: E402

out, episodes = sys.argv[1], int(sys.argv[2])
features = {
    "action": {"dtype": "float32", "shape": (6,), "names": None},
    "observation.state": {"dtype": "float32", "shape": (4,), "names": None},
    "observation.images.top": {
        "dtype": "video",
        "shape": (32, 32, 3),
        "names": ["height", "width", "channels"],
    },
}
ds = LeRobotDataset.create("local/small", 30, root=out, features=features, use_videos=True)
rng = np.random.default_rng(0)
for e in range(episodes):
    n = 20 + 7 * (e % 4)
    task = "Pick the red cube." if e % 3 else "Open the drawer."
    for k in range(n):
        img = np.zeros((32, 32, 3), dtype=np.uint8)
        img[:, :, 0] = (e * 37) % 256
        img[:, :, 1] = (k * 9) % 256
        img[:16, :, 2] = 200
        ds.add_frame({
            "action": rng.normal(size=6).astype(np.float32),
            "observation.state": rng.normal(size=4).astype(np.float32),
            "observation.images.top": img,
            "task": task,
        })
    ds.save_episode()
ds.finalize()
print(ds.num_episodes)
