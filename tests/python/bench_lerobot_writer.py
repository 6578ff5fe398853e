"""The lerobot side of `dexjoco-dev bench convert`: writes the same raw episodes with
lerobot's own dataset writer (LeRobotDataset.create / add_frame / save_episode /
finalize), offline, so that its wall time and peak memory can be compared with ours.

usage: bench_lerobot_writer.py RAW_DIR OUT_ROOT FPS
RAW_DIR holds DexJoCo raw episode folders (replay.zarr + videos/front.mp4), taken in
sorted order; action = data/action, observation.state = data/state[:, :23].
Prints {"episodes": N, "frames": M}.
"""
import json
import os
import sys
from pathlib import Path

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

import av  # noqa: E402
import numpy as np  # noqa: E402
import zarr  # noqa: E402
from lerobot.datasets.lerobot_dataset import LeRobotDataset  # noqa: E402

raw, out, fps = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
episodes = sorted(p.parent for p in raw.rglob("replay.zarr"))
first = zarr.open(str(episodes[0] / "replay.zarr"), "r")
with av.open(str(episodes[0] / "videos/front.mp4")) as c:
    s = c.streams.video[0]
    h, w = s.codec_context.height, s.codec_context.width
features = {
    "action": {"dtype": "float32", "shape": (first["data/action"].shape[1],), "names": None},
    "observation.state": {"dtype": "float32", "shape": (23,), "names": None},
    "observation.images.front": {"dtype": "video", "shape": (h, w, 3), "names": ["height", "width", "channels"]},
}
ds = LeRobotDataset.create("local/bench", fps, root=out, features=features, use_videos=True)
frames = 0
for ep in episodes:
    z = zarr.open(str(ep / "replay.zarr"), "r")
    action = z["data/action"][:].astype(np.float32)
    state = z["data/state"][:, :23].astype(np.float32)
    with av.open(str(ep / "videos/front.mp4")) as c:
        images = [f.to_ndarray(format="rgb24") for f in c.decode(video=0)]
    for k in range(len(action)):
        ds.add_frame({
            "action": action[k],
            "observation.state": state[k],
            "observation.images.front": images[k],
            "task": "Move the mouse to the purple mouse pad and click the left mouse button.",
        })
    ds.save_episode()
    frames += len(action)
ds.finalize()
print(json.dumps({"episodes": len(episodes), "frames": frames}))
