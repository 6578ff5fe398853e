"""The generation loop of `dexjoco-data generate` written in Python on the DexJoCo reference
environments (MuJoCo's Python bindings, the reference controller and task logic), for
`dexjoco-dev bench generate` (reference venv only).

The job (JSON, written by the bench) names the task and gives, per attempt, the state
to restore, each arm's target at reset and, per subtask in order, the source segment our
run chose: the MuJoCo body (or geom) of the subtask's object, the object's pose when the
segment began in the source, the arms and the targets. Per attempt this script does what
ours does: restore the reset, and for each subtask read the object's pose now, carry the
segment's target poses by `now * src^-1`, bridge from the arm's last target (slerp, at
the bench's speeds), step the reference environment with each action, stop at the task's
success. It does not evaluate the subtasks' end predicates (the reference has none), so
it never waits for one: a lower bound of the Python loop's cost.

    python generate_loop.py JOB.json

prints {"attempts", "steps", "successes", "seconds", "per_attempt"} as JSON.
"""

from __future__ import annotations

import json
import math
import sys
import time

import reference_arithmetic  # noqa: F401  before numpy

import mujoco
import numpy as np

import dexjoco_reference as ref
from dexjoco.tasks.state_restorers import restore_initial_state


def qmul(a, b):
    out = np.empty(4)
    mujoco.mju_mulQuat(out, np.asarray(a, float), np.asarray(b, float))
    return out


def qinv(q):
    out = np.empty(4)
    mujoco.mju_negQuat(out, np.asarray(q, float))
    return out


def rotate(q, v):
    out = np.empty(3)
    mujoco.mju_rotVecQuat(out, np.asarray(v, float), np.asarray(q, float))
    return out


def compose(a, b):
    """Pose a * b, poses as (pos[3], quat[4] wxyz)."""
    return a[0] + rotate(a[1], b[0]), qmul(a[1], b[1])


def inverse(a):
    qi = qinv(a[1])
    return -rotate(qi, a[0]), qi


def angle(a, b):
    d = abs(float(np.dot(a, b)))
    return 2.0 * math.acos(min(1.0, d))


def slerp(a, b, t):
    d = float(np.dot(a, b))
    if d < 0.0:
        b, d = -b, -d
    if d > 0.9995:
        q = a + t * (b - a)
        return q / np.linalg.norm(q)
    th = math.acos(d)
    return (math.sin((1 - t) * th) * a + math.sin(t * th) * b) / math.sin(th)


def object_pose(model, data, obj):
    if obj["kind"] == "joint":
        b = model.jnt_bodyid[model.joint(obj["name"]).id]
        return data.xpos[b].copy(), data.xquat[b].copy()
    if obj["kind"] == "geom":
        g = model.geom(obj["name"]).id
        q = np.empty(4)
        mujoco.mju_mat2Quat(q, data.geom_xmat[g])
        return data.geom_xpos[g].copy(), q
    b = model.body(obj["name"]).id
    return data.xpos[b].copy(), data.xquat[b].copy()


def run_attempt(env, config, task, attempt, options, width):
    env.reset()
    restore_initial_state(env, task, config, np.asarray(attempt["state0"], float))
    u = env.unwrapped
    model, data = u._model, u._data
    last = [
        (np.asarray(t[:3], float), np.asarray(t[3:7], float), np.asarray(t[7:], float))
        for t in attempt["targets0"]
    ]
    steps = 0
    per_arm = width // len(last)

    def step():
        action = np.zeros(width)
        for a, (p, q, h) in enumerate(last):
            action[a * per_arm : a * per_arm + 3] = p
            action[a * per_arm + 3 : a * per_arm + 7] = q
            action[a * per_arm + 7 : a * per_arm + 23] = h
        _obs, _rew, _done, _trunc, info = u.step(action)
        return bool(info.get("succeed", False))

    for seg in attempt["segments"]:
        now = object_pose(model, data, seg["object"])
        src = (np.asarray(seg["object_pose"][:3]), np.asarray(seg["object_pose"][3:]))
        delta = compose(now, inverse(src))
        targets = np.asarray(seg["targets"], float)  # steps x arms x 23
        carried = []
        for row in targets:
            carried.append(
                [compose(delta, (r[:3], r[3:7])) + (r[7:],) for r in row]
            )
        first = carried[0]
        n = options["bridge_min_steps"]
        for k, a in enumerate(seg["arms"]):
            d = float(np.linalg.norm(first[k][0] - last[a][0]))
            n = max(
                n,
                math.ceil(d / options["bridge_m_per_step"]),
                math.ceil(angle(first[k][1], last[a][1]) / options["bridge_rad_per_step"]),
            )
        start = [last[a] for a in seg["arms"]]
        for s in range(1, n + 1):
            t = s / (n + 1)
            for k, a in enumerate(seg["arms"]):
                p0, q0, h0 = start[k]
                p1, q1, h1 = first[k]
                last[a] = (p0 + t * (p1 - p0), slerp(q0, q1, t), h0 + t * (h1 - h0))
            steps += 1
            if step():
                return steps, True
        for row in carried:
            for k, a in enumerate(seg["arms"]):
                last[a] = row[k]
            steps += 1
            if step():
                return steps, True
    return steps, False


def main(path):
    job = json.loads(open(path).read())
    task = job["task"]
    config = ref.CONFIG_MAPPING[task]()
    env = config.get_environment(
        policy_mode=True,
        render_mode="rgb_array",
        randomize=False,
        randomize_dynamics=False,
        seed=1,
    )
    total_steps = successes = 0
    t0 = time.perf_counter()
    outcomes = []
    for attempt in job["attempts"]:
        steps, ok = run_attempt(env, config, task, attempt, job["options"], job["action_width"])
        total_steps += steps
        successes += int(ok)
        outcomes.append(ok)
    seconds = time.perf_counter() - t0
    env.close()
    n = len(job["attempts"])
    print(
        json.dumps(
            {
                "attempts": n,
                "steps": total_steps,
                "successes": successes,
                "outcomes": outcomes,
                "seconds": seconds,
                "per_attempt": seconds / max(n, 1),
            }
        )
    )


if __name__ == "__main__":
    main(sys.argv[1])
