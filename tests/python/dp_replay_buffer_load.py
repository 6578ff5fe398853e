"""Opens a replay buffer with Diffusion Policy's own ReplayBuffer class (zarr 2.x).

Usage: dp_replay_buffer_load.py DIFFUSION_POLICY_DIR ZARR_PATH

DIFFUSION_POLICY_DIR holds diffusion_policy/common/replay_buffer.py of
real-stanford/diffusion_policy at the commit the test pins (not vendored into this repo).
Prints JSON: episode ends, per array dtype/shape/chunks/compressor, the low-dimensional
arrays, and per image frame its mean colour; both of ReplayBuffer's backends (zarr on
disk, numpy in memory) must agree.
"""

import hashlib
import json
import sys

import numpy as np
import zarr

dp_dir, path = sys.argv[1], sys.argv[2]
source = f"{dp_dir}/diffusion_policy/common/replay_buffer.py"
sys.path.insert(0, dp_dir)
from diffusion_policy.common.replay_buffer import ReplayBuffer  # noqa: E402

assert zarr.__version__.startswith("2."), zarr.__version__

disk = ReplayBuffer.create_from_path(path, mode="r")
mem = ReplayBuffer.copy_from_path(path)
assert disk.backend == "zarr" and mem.backend == "numpy"
assert list(disk.episode_ends[:]) == list(mem.episode_ends[:])
out = {
    "replay_buffer_sha256": hashlib.sha256(open(source, "rb").read()).hexdigest(),
    "n_episodes": int(disk.n_episodes),
    "n_steps": int(disk.n_steps),
    "episode_ends": [int(e) for e in disk.episode_ends[:]],
    "episode_lengths": [int(x) for x in disk.episode_lengths],
    "arrays": {},
}
for key, arr in disk.items():
    a = arr[:]
    assert np.array_equal(a, mem[key]), key
    info = {
        "dtype": str(arr.dtype),
        "shape": list(arr.shape),
        "chunks": list(arr.chunks),
        "compressor": arr.compressor.get_config() if arr.compressor else None,
    }
    if a.ndim == 4:
        info["frame_means"] = a.reshape(a.shape[0], -1, a.shape[-1]).mean(axis=1).tolist()
    else:
        info["values"] = a.tolist()
    out["arrays"][key] = info
# Per-episode access as Diffusion Policy's datasets use it.
last = disk.get_episode(disk.n_episodes - 1)
out["last_episode_action_len"] = int(len(last["action"]))
print(json.dumps(out))
