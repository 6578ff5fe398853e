"""Reads the depth of converted datasets back with the real readers and compares it with
augment's depth archives.

usage: depth_check.py V3_ROOT DP_DIR ZARR CAMERA=NPZ[,NPZ...] ...

V3_ROOT: a LeRobot v3.0 dataset made with `convert --depth` (read with lerobot 0.6.1's
LeRobotDataset, offline); DP_DIR: Diffusion Policy's checkout (its ReplayBuffer);
ZARR: a replay buffer made with `convert --format diffusion-policy --depth`; then per
camera its archives in episode order (no leading frame skipped).

Prints JSON: lerobot's depth keys, per camera: the codes of the dataset's depth video
(decoded with PyAV as gray12le) against lerobot's quantize_depth of the archive (mismatches,
largest difference), every item's depth as LeRobotDataset returns it against lerobot's own
dequantize(quantize(archive)) in mm (mismatches) and against the archive (largest error in
mm, and pixels beyond half a code step plus the mm rounding), the stored statistics; and
Diffusion Policy's data/<camera>_depth (dtype, shape, chunks, bitwise equal to the archives);
and, when the dataset has them, each episode's outcome/randomization columns and every item's
privileged.state with its names.
"""

import json
import math
import os
import sys

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

import av  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402

from lerobot.datasets.depth_utils import dequantize_depth, quantize_depth  # noqa: E402
from lerobot.datasets.lerobot_dataset import LeRobotDataset  # noqa: E402

v3_root, dp_dir, zarr_path = sys.argv[1], sys.argv[2], sys.argv[3]
cameras = {}
for arg in sys.argv[4:]:
    name, paths = arg.split("=", 1)
    cameras[name] = [np.load(p)["depth"] for p in paths.split(",")]

ds = LeRobotDataset("local/dexjoco-depth", root=v3_root, video_backend="pyav")
out = {"depth_keys": list(ds.meta.depth_keys), "len": len(ds), "cameras": {}}
# Half a code step of the log scale, as a factor on (depth + shift).
step = (math.log(10.0 + 3.5) - math.log(0.01 + 3.5)) / 4095
for name, archives in cameras.items():
    key = f"observation.images.{name}_depth"
    source = np.concatenate(archives)  # (T, H, W) float32 metres, episodes in order
    want_codes = np.stack([quantize_depth(f, video_backend=None) for f in source])
    path = os.path.join(v3_root, "videos", key, "chunk-000", "file-000.mp4")
    with av.open(path) as c:
        codes = np.stack([f.to_ndarray(format="gray12le") for f in c.decode(video=0)])
    cam = {
        "video_frames": int(codes.shape[0]),
        "codes": int(codes.size),
        "code_mismatches": int((codes != want_codes).sum()) if codes.shape == want_codes.shape else -1,
        "code_max_diff": int(np.abs(codes.astype(np.int32) - want_codes.astype(np.int32)).max())
        if codes.shape == want_codes.shape
        else -1,
    }
    got = np.stack([ds[i][key].numpy() for i in range(len(ds))])  # (N, 1, H, W) mm
    # The reader dequantizes the stream's decoded codes (float32 torch arithmetic).
    expect_mm = np.stack(
        [dequantize_depth(torch.from_numpy(c.astype(np.int32)), output_unit="mm").numpy() for c in codes]
    )
    cam["item_shape"] = list(got.shape[1:])
    cam["item_dtype"] = str(got.dtype)
    cam["item_mismatches"] = int((got != expect_mm).sum())
    source_mm = source[:, None] * 1000.0
    err = np.abs(got - source_mm)
    bound = (source_mm + 3500.0) * (math.exp(step / 2) - 1) + 0.5 + 1e-3
    cam["max_err_mm"] = float(err.max())
    cam["beyond_bound"] = int((err > bound).sum())
    stats = ds.meta.stats[key]
    cam["stats"] = {k: np.asarray(v).tolist() for k, v in stats.items()}
    cam["source_min_mm"] = float(source.min()) * 1000.0
    cam["source_max_mm"] = float(source.max()) * 1000.0
    out["cameras"][name] = cam

# The labels (episode metadata columns) and the privileged state, when the dataset has them.
cols = [k for k in ds.meta.episodes.column_names if k.startswith(("outcome/", "randomization/"))]
out["labels"] = [{k: ds.meta.episodes[i][k] for k in cols} for i in range(ds.meta.total_episodes)]
if "privileged.state" in ds.meta.features:
    out["privileged_names"] = ds.meta.features["privileged.state"]["names"]
    out["privileged"] = [ds[i]["privileged.state"].tolist() for i in range(len(ds))]
    out["episode_index"] = [int(ds[i]["episode_index"]) for i in range(len(ds))]

sys.path.insert(0, dp_dir)
from diffusion_policy.common.replay_buffer import ReplayBuffer  # noqa: E402

rb = ReplayBuffer.create_from_path(zarr_path, mode="r")
out["dp"] = {}
for name, archives in cameras.items():
    arr = rb[f"{name}_depth"]
    a = arr[:]
    source = np.concatenate(archives)
    out["dp"][name] = {
        "dtype": str(a.dtype),
        "shape": list(a.shape),
        "chunks": list(arr.chunks),
        "compressor": arr.compressor.get_config()["id"] if arr.compressor else None,
        "bitwise_equal": bool(a.shape == source.shape and np.array_equal(a.view(np.uint32), source.view(np.uint32))),
    }
print(json.dumps(out))
