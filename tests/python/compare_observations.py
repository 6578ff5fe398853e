"""Compares two recorded first observations (`policy_server.py record`'s npz files):
the same keys, prompt, state and images (shape, largest difference in levels). Prints JSON.

    python compare_observations.py THEIRS.npz OURS.npz
"""

import json
import sys

import numpy as np


def main():
    a, b = np.load(sys.argv[1]), np.load(sys.argv[2])
    keys_a = sorted(k for k in a.files if k.startswith("0/"))
    keys_b = sorted(k for k in b.files if k.startswith("0/"))
    out = {
        "keys": keys_a,
        "keys_equal": keys_a == keys_b,
        "prompt_equal": str(a["0/prompt"]) == str(b["0/prompt"]),
        "state_max_diff": float(np.max(np.abs(a["0/state"] - b["0/state"]))),
        "images": {},
    }
    for k in keys_a:
        name = k[2:]
        if name in ("state", "prompt") or a[k].ndim != 3:
            continue
        x, y = a[k], b[k]
        same = x.shape == y.shape and x.dtype == y.dtype
        diff = np.abs(x.astype(int) - y.astype(int)) if same else None
        out["images"][name] = {
            "shape_equal": same,
            "dtype": str(x.dtype),
            "max_diff": int(diff.max()) if same else None,
            "share_differing": float((diff > 0).mean()) if same else None,
        }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
