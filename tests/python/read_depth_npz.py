"""Loads a depth archive as the DexJoCo tools do (numpy.load) and prints JSON: members,
dtype, shape, min/max and a few pixels.

usage: read_depth_npz.py FILE.npz
"""
import json
import sys

import numpy as np


def main():
    with np.load(sys.argv[1]) as z:
        members = list(z.keys())
        d = z["depth"]
    t, h, w = d.shape
    print(json.dumps({
        "members": members,
        "dtype": str(d.dtype),
        "shape": list(d.shape),
        "min": float(d.min()),
        "max": float(d.max()),
        "centre_last": float(d[t - 1, h // 2, w // 2]),
        "corner_first": float(d[0, 0, 0]),
    }))


if __name__ == "__main__":
    main()
