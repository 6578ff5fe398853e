"""Times random access to a LeRobot v3.0 dataset as a training data loader does it:
lerobot's own LeRobotDataset (offline, root=) with one video backend, items at seeded
random indices, each `ds[i]` timed (decoding every camera's frame at that timestamp).
Prints JSON: ms per item (median, mean, p90), items, the dataset's bytes.

usage: lerobot_random_read.py ROOT BACKEND [ITEMS] [SEED]   (BACKEND: pyav or torchcodec)
"""
import json
import os
import random
import sys
import time

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

from lerobot.datasets.lerobot_dataset import LeRobotDataset  # noqa: E402

root, backend = sys.argv[1], sys.argv[2]
items = int(sys.argv[3]) if len(sys.argv) > 3 else 200
seed = int(sys.argv[4]) if len(sys.argv) > 4 else 0
ds = LeRobotDataset("local/dexjoco-bench", root=root, video_backend=backend)
rng = random.Random(seed)
indices = [rng.randrange(len(ds)) for _ in range(items)]
ds[indices[0]]  # warm up: open files, import decoders
times = []
for i in indices:
    t0 = time.perf_counter()
    ds[i]
    times.append((time.perf_counter() - t0) * 1e3)
times.sort()
size = sum(
    os.path.getsize(os.path.join(d, f)) for d, _, fs in os.walk(root) for f in fs
)
print(json.dumps({
    "backend": backend,
    "items": items,
    "ms_median": times[len(times) // 2],
    "ms_mean": sum(times) / len(times),
    "ms_p90": times[int(len(times) * 0.9)],
    "cameras": len(ds.meta.camera_keys),
    "frames": len(ds),
    "bytes": size,
}))
