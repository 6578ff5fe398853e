"""Writes one DexJoCo raw episode folder exactly as the reference recorder does (zarr-python 2):
<out>/replay.zarr with data/{action, action_rotvec, state, timestamp} float64 (state float32
with --float32-state), Blosc zstd clevel 5 bitshuffle, chunks (min(T, 2e6 // bytes_per_step),
*trailing), meta/episode_ends int64 (1,) chunks (1024,) no compressor, no .zattrs.

Prints the written arrays as JSON ({name: {"shape": [...], "values": [...]}}); floats are
printed in Python's shortest round-trip form, so they parse back bit-exactly.

usage: make_raw_fixture.py OUT_DIR TASK FRAMES SEED [--float32-state] [--no-rotvec] [--old-pick-bucket-order]
"""
import json
import sys

import numcodecs
import numpy as np
import zarr

from dexjoco_fixture_data import make_arrays

assert zarr.__version__.startswith("2."), zarr.__version__


def main():
    out, task, frames, seed = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    flags = set(sys.argv[5:])
    arrays = make_arrays(task, frames, seed)
    expected_rotvec = arrays["action_rotvec"]
    if "--no-rotvec" in flags:
        del arrays["action_rotvec"]
    if "--old-pick-bucket-order" in flags:
        s = arrays["state"]
        s[:, 23:30], s[:, 30:37] = s[:, 30:37].copy(), s[:, 23:30].copy()
    if "--float32-state" in flags:
        arrays["state"] = arrays["state"].astype(np.float32)

    root = zarr.open_group(f"{out}/replay.zarr", mode="w")
    data = root.create_group("data")
    meta = root.create_group("meta")
    compressor = numcodecs.Blosc(cname="zstd", clevel=5, shuffle=numcodecs.Blosc.BITSHUFFLE)
    for name, arr in arrays.items():
        bytes_per_step = arr[0].nbytes if arr.ndim > 1 else arr.itemsize
        chunks = (min(frames, int(2e6 // bytes_per_step)),) + arr.shape[1:]
        data.create_dataset(name, data=arr, chunks=chunks, compressor=compressor, dtype=arr.dtype)
    meta.create_dataset("episode_ends", data=np.array([frames], dtype=np.int64), chunks=(1024,),
                        compressor=None, dtype="int64")
    out = {name: {"shape": list(a.shape), "dtype": str(a.dtype),
                  "values": [float(x) for x in a.ravel()]} for name, a in arrays.items()}
    # SciPy's rotation vectors, also when the array was left out (the reader computes it).
    out["scipy_action_rotvec"] = {"shape": list(expected_rotvec.shape), "dtype": "float64",
                                  "values": [float(x) for x in expected_rotvec.ravel()]}
    print(json.dumps(out))


if __name__ == "__main__":
    main()
