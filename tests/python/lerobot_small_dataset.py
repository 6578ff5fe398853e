"""Writes a small LeRobot v3.0 dataset with lerobot's own writer (LeRobotDataset.create /
add_frame / save_episode / finalize), as a dataset downloaded from the Hub is made:
EPISODES episodes of two tasks, lengths LENGTH + 7 * (i % 4), a 6-wide action, a 4-wide
state and one SIZExSIZE camera whose frames encode (episode, frame) as colours.

usage: lerobot_small_dataset.py OUT_ROOT EPISODES [SIZE (32)] [LENGTH (20)] [CAMERA (top)] [ACTION_WIDTH (6)]
With IDLE=k in the environment, episode i holds still at its start for k + i % 3 frames
(action all zeros) and at its end for k frames (action all ones).
"""
import os
import sys

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

import numpy as np  # noqa: E402
from lerobot.datasets.lerobot_dataset import LeRobotDataset  # noqa: E402

out, episodes = sys.argv[1], int(sys.argv[2])
size = int(sys.argv[3]) if len(sys.argv) > 3 else 32
length = int(sys.argv[4]) if len(sys.argv) > 4 else 20
camera = "observation.images." + (sys.argv[5] if len(sys.argv) > 5 else "top")
width = int(sys.argv[6]) if len(sys.argv) > 6 else 6
features = {
    "action": {"dtype": "float32", "shape": (width,), "names": None},
    "observation.state": {"dtype": "float32", "shape": (4,), "names": None},
    camera: {
        "dtype": "video",
        "shape": (size, size, 3),
        "names": ["height", "width", "channels"],
    },
}
ds = LeRobotDataset.create("local/small", 30, root=out, features=features, use_videos=True)
rng = np.random.default_rng(0)
idle = int(os.environ.get("IDLE", "0"))
for e in range(episodes):
    n = length + 7 * (e % 4)
    task = "Pick the red cube." if e % 3 else "Open the drawer."
    for k in range(n):
        img = np.zeros((size, size, 3), dtype=np.uint8)
        img[:, :, 0] = (e * 37) % 256
        img[:, :, 1] = (k * 9) % 256
        img[: size // 2, :, 2] = 200
        action = rng.normal(size=width).astype(np.float32)
        if idle and k < idle + e % 3:
            action[:] = 0.0
        elif idle and k >= n - idle:
            action[:] = 1.0
        ds.add_frame({
            "action": action,
            "observation.state": rng.normal(size=4).astype(np.float32),
            camera: img,
            "task": task,
        })
    ds.save_episode()
ds.finalize()
print(ds.num_episodes)
