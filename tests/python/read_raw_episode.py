"""Reads an episode folder's replay.zarr with zarr-python 2 and prints JSON: every array's
metadata (.zarray as stored), values, and the files of the store (to check for .zattrs).

usage: read_raw_episode.py EPISODE_DIR
"""
import json
import os
import sys

import zarr

assert zarr.__version__.startswith("2."), zarr.__version__


def main():
    path = os.path.join(sys.argv[1], "replay.zarr")
    root = zarr.open(path, mode="r")
    out = {"arrays": {}, "files": []}
    for group in ("data", "meta"):
        for name, arr in root[group].arrays():
            with open(os.path.join(path, group, name, ".zarray")) as f:
                zarray = json.load(f)
            a = arr[...]
            out["arrays"][f"{group}/{name}"] = {
                "zarray": zarray,
                "dtype": str(a.dtype),
                "shape": list(a.shape),
                "compressor": arr.compressor.get_config() if arr.compressor else None,
                "values": [float(x) if a.dtype.kind == "f" else int(x) for x in a.ravel()],
            }
    for dirpath, _, files in os.walk(path):
        for f in files:
            out["files"].append(os.path.relpath(os.path.join(dirpath, f), path))
    out["files"].sort()
    print(json.dumps(out))


if __name__ == "__main__":
    main()
