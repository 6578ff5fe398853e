"""Deterministic, valid DexJoCo episode arrays for the interop fixtures (numpy + SciPy).

Shared by make_raw_fixture.py and make_mcap_fixture.py. Values follow the raw format
facts: quaternions wxyz of unit norm, hand targets inside the Allegro ranges, the
task's privileged layout with dh in [0, 0.05], timestamp = arange(T) / 30.
"""
import numpy as np
from scipy.spatial.transform import Rotation

# task id -> (arms, state width, privileged layout after proprioception)
TASKS = {
    "hammer_nail": (1, 38, ["pose:hammer", "pose:nail", "dh"]),
    "click_mouse": (1, 31, ["pose:mouse", "dh"]),
    "pick_bucket": (1, 38, ["pose:bucket", "pose:food", "dh"]),
    "pinch_tongs": (1, 31, ["pose:tongs", "dh"]),
    "fold_glasses": (1, 38, ["pose:glasses", "pose:case", "dh"]),
    "water_plant": (1, 38, ["pose:spray", "pose:plant", "dh"]),
    "bimanual_unlock_ipad": (2, 61, ["pose:stand", "pose:ipad", "dh"]),
    "bimanual_hanoi": (2, 50, ["pos:base", "dh"]),
    "bimanual_assembly": (2, 61, ["pose:tray", "pose:peg", "dh"]),
    "bimanual_microwave_cook": (2, 61, ["pose:hot_dog", "pose:microwave", "dh"]),
    "bimanual_photograph": (2, 61, ["pose:camera", "pose:logo", "dh"]),
}

_B, _P, _M, _D = (-0.47, 0.47), (-0.196, 1.61), (-0.174, 1.709), (-0.227, 1.618)
HAND_RANGES = np.array([_B, _P, _M, _D] * 3 + [(0.263, 1.396), (-0.105, 1.163), (-0.189, 1.644), (-0.162, 1.719)])


def unit_quats(rng, n):
    q = rng.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def make_arrays(task, frames, seed):
    """Returns dict action, action_rotvec, state, timestamp (float64)."""
    arms, s_dim, priv = TASKS[task]
    rng = np.random.default_rng(seed)
    action = np.zeros((frames, 23 * arms))
    for a in range(arms):
        o = 23 * a
        action[:, o:o + 3] = rng.uniform(-0.5, 0.5, size=(frames, 3)) + [0, 0, 1.1]
        action[:, o + 3:o + 7] = unit_quats(rng, frames)
        lo, hi = HAND_RANGES[:, 0], HAND_RANGES[:, 1]
        action[:, o + 7:o + 23] = lo + (hi - lo) * rng.uniform(0, 1, size=(frames, 16))
    rotvec = np.zeros((frames, 22 * arms))
    for a in range(arms):
        i, o = 23 * a, 22 * a
        q = action[:, i + 3:i + 7]
        rotvec[:, o:o + 3] = action[:, i:i + 3]
        rotvec[:, o + 3:o + 6] = Rotation.from_quat(q, scalar_first=True).as_rotvec()
        rotvec[:, o + 6:o + 22] = action[:, i + 7:i + 23]
    state = np.zeros((frames, s_dim))
    for a in range(arms):
        state[:, 7 * a:7 * a + 3] = rng.uniform(-0.5, 0.5, size=(frames, 3))
        state[:, 7 * a + 3:7 * a + 7] = unit_quats(rng, frames)
    state[:, 7 * arms:23 * arms] = rng.uniform(-0.1, 0.1, size=(frames, 16 * arms))
    dh = rng.uniform(0, 0.05)
    col = 23 * arms
    for p in priv:
        if p.startswith("pose:"):
            name = p[5:]
            y = 0.17 if name == "food" else -0.22
            pos = [rng.uniform(-0.35, -0.15), y, 0.95 + dh]
            state[:, col:col + 3] = pos
            state[:, col + 3:col + 7] = unit_quats(rng, 1)[0]
            col += 7
        elif p.startswith("pos:"):
            state[:, col:col + 3] = [rng.uniform(-0.25, -0.2), 0.0, 0.92 + dh]
            col += 3
        else:
            state[:, col] = dh
            col += 1
    assert col == s_dim, (task, col, s_dim)
    timestamp = np.arange(frames) / 30
    return {"action": action, "action_rotvec": rotvec, "state": state, "timestamp": timestamp}
