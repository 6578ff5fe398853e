"""Opens an episode folder's replay.zarr with zarr-python 2, reads every array as the
DexJoCo tools do, and prints JSON: the root group's attributes and each array's shape.

usage: zarr_root_attrs.py EPISODE_DIR
"""
import json
import os
import sys

import zarr

assert zarr.__version__.startswith("2."), zarr.__version__

root = zarr.open(os.path.join(sys.argv[1], "replay.zarr"), mode="r")
shapes = {}
for group in ("data", "meta"):
    for name, arr in root[group].arrays():
        shapes[f"{group}/{name}"] = list(arr[...].shape)
print(json.dumps({"attrs": dict(root.attrs), "shapes": shapes}))
