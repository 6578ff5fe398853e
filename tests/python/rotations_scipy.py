"""SciPy's rotation conversions for the rotation test (crates/core/tests/scipy_rotations.rs).

Reads a JSON file {"quats": [[w, x, y, z], ...], "rotvecs": [[x, y, z], ...]} and prints
{"rotvec": [...], "quat": [...]}: quaternion (wxyz) -> rotation vector in the DexJoCo
convention (normalize; the zero quaternion gives the zero vector, where SciPy would
raise), and rotation vector -> quaternion (wxyz).
"""
import json
import sys

import numpy as np
from scipy.spatial.transform import Rotation as R


def main() -> None:
    with open(sys.argv[1]) as f:
        data = json.load(f)
    rotvec = []
    for q in data["quats"]:
        q = np.asarray(q, dtype=np.float64)
        if np.linalg.norm(q) < 1e-12:
            rotvec.append([0.0, 0.0, 0.0])
        else:
            rotvec.append(R.from_quat(q, scalar_first=True).as_rotvec().tolist())
    quat = [R.from_rotvec(np.asarray(r, dtype=np.float64)).as_quat(scalar_first=True).tolist() for r in data["rotvecs"]]
    json.dump({"rotvec": rotvec, "quat": quat}, sys.stdout)


if __name__ == "__main__":
    main()
