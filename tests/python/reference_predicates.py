"""The reference environments' success and failure conditions on sampled MuJoCo states
(reference venv only; `crates/sim/tests/reference_predicates.rs` runs it).

For each task: the reference environment is made and reset (`dexjoco_reference.make_env`),
then a few hundred states are sampled near each threshold of its conditions by moving
what the conditions read (object free joints, hinges, the Hanoi disks' speeds) from the
reset state, `mj_forward` each, and ask the reference code itself for its per-step
conditions, before its temporal logic (hold counters are preset one short of their target,
latches set to the prior state the sample names; the hammer's speed window holds the
samples of a priming state and the sample). Where a condition is inline code of the
reference `step` or `_compute_success`, the expression is evaluated on the reference env's
own attributes, with the file and line cited. The answers are keyed by the name of the
corresponding node of this project's task spec (`TASKS` below), so the Rust test can
evaluate our spec on the same states and compare.

    python reference_predicates.py --out DIR [--samples N] [--tasks T1,T2]

writes DIR/<task>.f64 (little-endian float64: the state[0] row, the FULLPHYSICS state after
reset, then per sample a priming state (zeros unless the sample has a prior) and the
sample's FULLPHYSICS state) and DIR/manifest.json (per task: widths, the model's disable
flags, the answers per node or `node.output`, each sample's prior flag, how the priming
state is applied: `step` (a latch set on it) or `substep` (the hammer's speed sample), and
the steps each sample is held for).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import reference_arithmetic  # noqa: F401  before numpy: pins its SIMD loops and OpenBLAS's

import mujoco
import numpy as np

import dexjoco_reference as ref

FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS
SCALES = (0.003, 0.03, 0.3)


def _near(rng, value):
    """A value near `value` at a random relative scale, on either side."""
    return value * (1.0 + rng.choice(SCALES) * rng.uniform(-1.0, 1.0))


def _qadr(u, joint):
    return int(u._model.jnt_qposadr[u._model.joint(joint).id])


def _dadr(u, joint):
    return int(u._model.jnt_dofadr[u._model.joint(joint).id])


def _move_free(u, joint, current, target):
    """Translates a free joint so that a point of its body goes from `current` to `target`."""
    a = _qadr(u, joint)
    u._data.qpos[a : a + 3] += np.asarray(target) - np.asarray(current)


def _yaw_free(u, joint, angle):
    """Turns a free joint's orientation about the world z axis."""
    a = _qadr(u, joint)
    q = np.array([np.cos(angle / 2), 0.0, 0.0, np.sin(angle / 2)])
    out = np.zeros(4)
    mujoco.mju_mulQuat(out, q, u._data.qpos[a + 3 : a + 7].copy())
    u._data.qpos[a + 3 : a + 7] = out


def _set_joint_near(u, rng, joint, value, base=0.0):
    u._data.qpos[_qadr(u, joint)] = base + _near(rng, value)


def _forward(u):
    mujoco.mj_forward(u._model, u._data)


# ---------------------------------------------------------------- click_mouse


def _sample_click_mouse(u, rng):
    pad = u._data.geom_xpos[u._mousepad_geom_id].copy()
    mouse = u._data.sensor("mouse_pos").data.copy()
    angle = rng.uniform(0, 2 * np.pi)
    if rng.random() < 0.5:  # the pad's radius, height inside
        r, dz = _near(rng, u._mousepad_radius), rng.uniform(-0.04, 0.04)
    else:  # the height tolerance, radius inside
        r, dz = rng.uniform(0, 0.14), rng.choice([-1, 1]) * _near(rng, 0.05)
    _move_free(u, "mouse_root", mouse, pad + [r * np.cos(angle), r * np.sin(angle), dz])
    _set_joint_near(u, rng, "mouse_joint_0", 0.001, u._mouse_joint0_init)


def _answer_click_mouse(u, _prior, _primed):
    on_pad, click = u._mouse_in_mousepad(), u._detect_click()
    # panda_click_mouse_env.py:592: the display turns blue when both hold.
    u._display_blue = on_pad and click
    u._success_trigger_target = 1
    u._success_trigger_count = 0
    clicked = u._compute_success()
    return {"on_pad": on_pad, "click": click, "click_on_pad": on_pad and click, "clicked": clicked}


# ---------------------------------------------------------------- fold_glasses


def _sample_fold_glasses(u, rng):
    box = u._model.body("open_box").pos.copy()
    glass = u._data.sensor("glass_pos").data.copy()
    local = rng.uniform([-0.14, -0.14, -0.04], [0.14, 0.14, 0.02])
    k = rng.integers(0, 4)
    if k < 3:  # one face of the cavity
        bounds = ((-0.145, 0.145), (-0.145, 0.145), (-0.045, 0.0275))[k]
        local[k] = _near(rng, bounds[rng.integers(0, 2)])
    _move_free(u, "glass_root", glass, box + local)
    for j in ("glass_joint_0", "glass_joint_1"):
        _set_joint_near(u, rng, j, 1.1)


def _answer_fold_glasses(u, _prior, _primed):
    # panda_fold_glasses_env.py:549-550: the hinge conditions, inline.
    j0 = float(u._data.sensor("glass_joint_0_pos").data[0])
    j1 = float(u._data.sensor("glass_joint_1_pos").data[0])
    u._success_trigger_target = 1
    u._success_trigger_count = 0
    stowed = u._compute_success()
    return {"left_folded": j0 > 1.1, "right_folded": j1 > 1.1, "stowed": stowed}


# ---------------------------------------------------------------- pick_bucket


def _bucket_corners(u):
    ids = [u._model.site(f"bucket_ref_{i}").id for i in range(8)]
    return np.array(u._data.site_xpos[ids])


def _sample_pick_bucket(u, rng):
    _yaw_free(u, "bucket_root", rng.uniform(-0.3, 0.3))
    a = _qadr(u, "bucket_root")
    u._data.qpos[a + 2] += _near(rng, 0.15) if rng.random() < 0.6 else rng.uniform(0, 0.3)
    _forward(u)
    corners = _bucket_corners(u)
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    point = rng.uniform(lo, hi)
    k = rng.integers(0, 3)
    side = (lo, hi)[rng.integers(0, 2)]
    point[k] = side[k] + rng.choice(SCALES) * 0.1 * rng.uniform(-1, 1)
    _move_free(u, "boxed_food_0_freejoint", u._data.sensor("boxed_food_0_pos").data.copy(), point)


def _answer_pick_bucket(u, _prior, _primed):
    # panda_pick_bucket_env.py:586-596, inline: the food within the corners' box, the
    # bottom sites 0.15 m above their reset heights.
    box_pos = np.array(u._data.sensor("boxed_food_0_pos").data)
    corners = _bucket_corners(u)
    inside = bool(np.all(box_pos >= corners.min(axis=0)) and np.all(box_pos <= corners.max(axis=0)))
    bottom_z = u._data.site_xpos[u._bucket_bottom_site_ids, 2]
    lifted = bool(np.all(bottom_z - u._bucket_bottom_z0 >= 0.15))
    return {"food_in_bucket": inside, "bucket_lifted": lifted, "done": bool(u._compute_success())}


# ---------------------------------------------------------------- pinch_tongs


def _sample_pinch_tongs(u, rng):
    tongs = u._data.sensor("tongs_pos").data.copy()
    target = tongs.copy()
    target[2] = u._lift_z + rng.choice(SCALES) * 0.1 * rng.uniform(-1, 1)
    _move_free(u, "tongs_root", tongs, target)
    _set_joint_near(u, rng, "joint_0", (-0.07, 0.1)[rng.integers(0, 2)])


def _prime_pinch_tongs(u, _rng):
    u._data.qpos[_qadr(u, "joint_0")] = 0.3


def _answer_pinch_tongs(u, prior, _primed):
    u._pinch_in_progress = prior
    u._update_pinch_count()
    u._pinch_count, u._success_started, u._success_counter = 3, True, 29
    lifted = u._compute_success()
    return {"armed": bool(u._pinch_in_progress), "lifted": bool(lifted)}


# ---------------------------------------------------------------- water_plant


def _sample_water_plant(u, rng):
    plant = u._data.body("plant").xpos.copy()
    point = u._data.site_xpos[u._model.site("ref_point").id].copy()
    angle = rng.uniform(0, 2 * np.pi)
    if rng.random() < 0.5:
        r, dz = _near(rng, 0.2), rng.uniform(-0.19, 0.19)
    else:
        r, dz = rng.uniform(0, 0.19), rng.choice([-1, 1]) * _near(rng, 0.2)
    _move_free(u, "spray_root", point, plant + [r * np.cos(angle), r * np.sin(angle), dz])
    _set_joint_near(u, rng, "joint_0", (0.25, 0.34)[rng.integers(0, 2)])


def _prime_water_plant(u, _rng):
    u._data.qpos[_qadr(u, "joint_0")] = 0.5


def _answer_water_plant(u, prior, _primed):
    # panda_water_plant_env.py:513-516, inline in step: the trigger's hysteresis.
    pos = float(u._data.sensor("spray_joint_0_pos").data[0])
    pulled = prior
    if pos < 0.25:
        pulled = False
    elif pos > 0.34:
        pulled = True
    u._trigger_pulled = pulled
    u._success_counter = 29
    # panda_water_plant_env.py:558-565, inline in _compute_success: the can's reference
    # point inside the cylinder about the plant (the subtask "point it at the plant").
    d = u._data.site_xpos[u._model.site("ref_point").id] - u._data.body("plant").xpos
    inside = d[0] * d[0] + d[1] * d[1] <= 0.2 * 0.2 and -0.2 <= d[2] <= 0.2
    watering, spilled = u._compute_success()
    return {
        "trigger": pulled,
        "watering": bool(watering),
        "spilled": bool(spilled),
        "over_plant": bool(inside),
    }


# ---------------------------------------------------------------- contacts


def _touching(u, joint, point, anchor, predicate, rng, direction=None):
    """Moves a free body along a direction (random unless given) so that `point()` (a
    point of it) lies at `anchor + direction * d`, `d` near the distance where
    `predicate()` turns false (found by bisection)."""
    direction = rng.normal(size=3) if direction is None else direction()
    direction /= np.linalg.norm(direction)

    def place(d):
        _move_free(u, joint, point(), anchor + direction * d)
        _forward(u)
        return predicate()

    # Deep overlaps may make no contact (a thin button inside a fingertip): the first
    # distance where it holds, from 0 out.
    lo = next((d for d in np.linspace(0.0, 0.05, 51) if place(d)), None)
    hi = 0.3
    if lo is None or place(hi):
        return
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if place(mid) else (lo, mid)
    place(_near(rng, lo))


# ---------------------------------------------------------------- bimanual_microwave_cook


def _sample_bimanual_microwave_cook(u, rng):
    _set_joint_near(u, rng, "microjoint", rng.choice([-1, 1]) * 0.01)
    dog = lambda: u._data.sensor("hot_dog_pos").data.copy()  # noqa: E731
    if rng.random() < 0.4:
        button = u._data.geom_xpos[u._model.geom("start_button").id].copy()
        _touching(u, "hot_dog_free", dog, button, lambda: u._geom_in_contact("start_button"), rng)
        return
    site = lambda n: u._model.site(n).pos  # noqa: E731
    lo = site("int_p0") - 0.01
    hi = np.array([site("int_px")[0], site("int_py")[1], site("int_pz")[2]]) + 0.01
    local = rng.uniform(lo, hi)
    k = rng.integers(0, 3)
    local[k] = (lo, hi)[rng.integers(0, 2)][k] + rng.choice(SCALES) * 0.05 * rng.uniform(-1, 1)
    body = u._data.body("microwave_object")
    _move_free(u, "hot_dog_free", dog(), body.xpos + body.xmat.reshape(3, 3) @ local)


def _answer_bimanual_microwave_cook(u, _prior, _primed):
    # panda_bimanual_microwave_cook_env.py:594-595, inline: the door's hinge within 1e-2.
    closed = abs(float(u._data.joint("microjoint").qpos[0])) < 1e-2
    return {
        "door_closed": closed,
        "food_inside": u.hot_dog_inside_microwave(margin=0.01),
        "start_pressed": u._geom_in_contact("start_button"),
    }


# ---------------------------------------------------------------- bimanual_photograph


def _rotation_to(a, b):
    """The quaternion of the shortest rotation taking unit vector a to b."""
    q = np.concatenate([[1.0 + np.dot(a, b)], np.cross(a, b)])
    return q / np.linalg.norm(q)


def _sample_bimanual_photograph(u, rng):
    a = _qadr(u, "camera_root")
    axis = u._data.geom_xmat[u._camera_axis_z_geom_id].reshape(3, 3)[:, 2].copy()
    tilt = np.deg2rad(_near(rng, 10.0) if rng.random() < 0.5 else rng.uniform(0, 9.5))
    side = rng.normal(size=3)
    side[0] = 0.0
    side /= np.linalg.norm(side)
    target = np.cos(tilt) * np.array([1.0, 0.0, 0.0]) + np.sin(tilt) * side
    turned = np.zeros(4)
    mujoco.mju_mulQuat(turned, _rotation_to(axis, target), u._data.qpos[a + 3 : a + 7].copy())
    u._data.qpos[a + 3 : a + 7] = turned
    _forward(u)
    view = lambda: u._data.site_xpos[u._view_site_id].copy()  # noqa: E731
    if rng.random() < 0.3:
        tip = u._data.geom_xpos[u._model.geom("fingertip_ff_right").id].copy()
        cap = lambda: u._data.geom_xpos[u._shutter_geom_id].copy()  # noqa: E731
        shutter = lambda: u._compute_success_metrics()[1]["shutter_pressed"]  # noqa: E731
        _touching(u, "camera_root", cap, tip, shutter, rng)
        return
    angle = rng.uniform(0, 2 * np.pi)
    if rng.random() < 0.5:
        r, h = _near(rng, 0.16), rng.uniform(-0.09, 0.09)
    else:
        r, h = rng.uniform(0, 0.15), rng.choice([-1, 1]) * _near(rng, 0.10)
    gid = u._target_region_geom_id
    region = u._data.geom_xmat[gid].reshape(3, 3)
    local = np.array([r * np.cos(angle), r * np.sin(angle), h])
    _move_free(u, "camera_root", view(), u._data.geom_xpos[gid] + region @ local)


def _answer_bimanual_photograph(u, _prior, _primed):
    _success, m = u._compute_success_metrics()
    return {
        "aimed": m["region_pass"],
        "level": m["angle_pass"],
        "shutter": m["shutter_pressed"],
    }


# ---------------------------------------------------------------- bimanual_assembly


def _peg_at_bottom(u):
    u._success_started, u._success_counter = True, 29
    return u._compute_success_metrics()


def _sample_bimanual_assembly(u, rng):
    # The peg upright (its collision cylinder's axis along world z), its end face coming
    # down on the hole's bottom.
    a = _qadr(u, "industreal_round_peg_8mm_joint")
    local = u._model.geom_quat[u._peg_geom_id]
    u._data.qpos[a + 3 : a + 7] = local * [1.0, -1.0, -1.0, -1.0]
    _forward(u)
    peg = lambda: u._data.geom_xpos[u._peg_geom_id].copy()  # noqa: E731
    bottom = u._data.geom_xpos[u._socket_bottom_geom_id].copy()
    bottom += rng.uniform(-0.01, 0.01, size=3) * [1, 1, 0]
    up = lambda: np.array([0.0, 0.0, 1.0]) + rng.normal(scale=0.3, size=3) * [1, 1, 0]  # noqa: E731
    _touching(u, "industreal_round_peg_8mm_joint", peg, bottom, lambda: _peg_at_bottom(u), rng, up)


def _answer_bimanual_assembly(u, _prior, _primed):
    return {"peg_at_bottom": bool(_peg_at_bottom(u))}


# ---------------------------------------------------------------- bimanual_unlock_ipad


def _fresh_keypad(u):
    u._unlock_index, u._unlock_failed, u._pressed_last = 0, False, set()
    u._buttons_hidden = u._unlock_pending = u._screen_unlocked = False


def _sample_bimanual_unlock_ipad(u, rng):
    digit = 1 if rng.random() < 0.4 else int(rng.integers(0, 10))
    gid = u._get_button_geom_id_by_digit(digit)
    tip = u._data.geom_xpos[sorted(u._finger_geom_ids)[rng.integers(0, 4)]].copy()

    def pressed():
        _fresh_keypad(u)
        u._update_button_visuals()
        return gid in u._pressed_last

    button = lambda: u._data.geom_xpos[gid].copy()  # noqa: E731
    # Along the button's axis (toward the finger), tilted a little.
    axis = u._data.geom_xmat[gid].reshape(3, 3)[:, 2].copy()
    sign = rng.choice([-1.0, 1.0])
    tilted = lambda: sign * axis + rng.normal(scale=0.2, size=3)  # noqa: E731
    _touching(u, "ipad_freejoint", button, tip, pressed, rng, tilted)


def _answer_bimanual_unlock_ipad(u, _prior, _primed):
    _fresh_keypad(u)
    u._update_button_visuals()
    return {"keypad.failed": u._unlock_failed, "keypad.index": u._unlock_index}


# ---------------------------------------------------------------- hammer_nail


def _hit(u):
    """The reference's hammer-nail contact: `_apply_hammer_nail_interaction` with no speed
    sample returns whether they touch and changes nothing."""
    u._vz_buf, u._nail_depth = [], 0.0
    return u._apply_hammer_nail_interaction()


def _face_z(u):
    return float(u._data.geom_xpos[u._face_gid][2])


def _sample_hammer_nail(u, rng):
    face = lambda: u._data.geom_xpos[u._face_gid].copy()  # noqa: E731
    head = u._data.geom_xpos[u._model.geom("nail_head").id].copy()
    down = lambda: np.array([0.0, 0.0, 1.0]) + rng.normal(scale=0.5, size=3)  # noqa: E731
    _touching(u, "hammer_joint", face, head, lambda: _hit(u), rng, down)


def _prime_hammer_nail(u, rng):
    """The substep before: the hammer higher by about the height one substep at the
    impact speed threshold covers (0.02 m/s over 0.02 s)."""
    u._data.qpos[_qadr(u, "hammer_joint") + 2] += _near(rng, 0.02 * u.control_dt)
    _forward(u)
    return _face_z(u)


def _answer_hammer_nail(u, prior, primed):
    # panda_hammer_nail_env.py:556-562, inline in step: one speed sample per substep,
    # (face z - previous face z) / control_dt, from the face height at reset.
    z_reset, z = u._prev_face_z, _face_z(u)
    heights = [z_reset, primed, z] if prior else [z_reset, z]
    u._vz_buf = [(b - a) / u.control_dt for a, b in zip(heights, heights[1:])]
    u._nail_depth = 0.0
    u._apply_hammer_nail_interaction()
    return {"nail": u._nail_depth > 0.0, "nail.depth": u._nail_depth}


# ---------------------------------------------------------------- bimanual_hanoi


def _offset(rng, tol):
    """A horizontal offset: mostly small, else near `tol` in length."""
    angle = rng.uniform(0, 2 * np.pi)
    r = _near(rng, tol) if rng.random() < 0.3 else rng.uniform(0, 0.6 * tol)
    return np.array([r * np.cos(angle), r * np.sin(angle), 0.0])


def _sample_bimanual_hanoi(u, rng):
    """The disks stacked on posts (the goal stack, or a random assignment that may invert
    a stack or leave a disk on the table), near the position, height and speed tolerances."""
    posts = u._get_post_world_positions()
    if rng.random() < 0.4:
        stacks = {"A": [], "B": [], "C": list(u._disk_names)}
        table = []
    else:
        stacks, table = {"A": [], "B": [], "C": []}, []
        for disk in rng.permutation(u._disk_names):
            where = rng.choice(["A", "B", "C", "table"], p=[0.3, 0.3, 0.3, 0.1])
            (table if where == "table" else stacks[where]).append(str(disk))
    tol, z_tol = u._post_assignment_tol, u._placement_height_tol
    for post, disks in stacks.items():
        height = u._base_top_world_z()
        for disk in disks:
            half = u._disk_half_height[disk]
            dz = rng.choice([-1, 1]) * _near(rng, z_tol) if rng.random() < 0.3 else 0.0
            z = height + half + dz
            height += 2 * half
            a = _qadr(u, disk + "_joint")
            u._data.qpos[a : a + 3] = posts[post] * [1, 1, 0] + [0, 0, z] + _offset(rng, tol)
    for disk in table:
        a = _qadr(u, disk + "_joint")
        z = u._base_top_world_z() + _near(rng, 0.06)
        u._data.qpos[a : a + 3] = posts["A"] * [1, 1, 0] + [0.0, 0.25, z]
    for disk in u._disk_names:
        if rng.random() < 0.3:
            d = _dadr(u, disk + "_joint")
            v = rng.normal(size=6)
            u._data.qvel[d : d + 6] = v / np.linalg.norm(v) * _near(rng, u._static_qvel_tol)


def _answer_bimanual_hanoi(u, _prior, _primed):
    # The state held for the illegal target's steps: a first call learns this state's
    # illegal reason, then the counters stand one short of their targets.
    u._illegal_trigger_reason, u._illegal_trigger_count = "", 0
    u._compute_success_metrics()
    held = u._illegal_trigger_target - 1
    u._illegal_trigger_count = held if u._illegal_trigger_reason else 0
    u._success_trigger_count = u._success_trigger_target - 1
    success, m = u._compute_success_metrics()
    return {"hanoi": success, "hanoi.illegal": m["illegal_state"], "hanoi.on_goal": _on_goal(u)}


def _on_goal(u):
    """The disks seated on the goal post C in the goal order from the bottom, when its stack
    is within the position and height tolerances (0 otherwise): the reference's own tower
    reconstruction and geometry check (`_reconstruct_tower_state`, `_tower_geometry_errors`)
    against its `target_stack` (panda_bimanual_hanoi_env.py, _compute_success_metrics)."""
    state = u._reconstruct_tower_state()
    stack = state["towers"]["C"]
    xy, height = u._tower_geometry_errors(
        stack, "C", state["disk_positions"], state["post_positions"], state["base_top_z"]
    )
    if not (xy <= u._post_assignment_tol and height <= u._placement_height_tol):
        return 0
    target = ["hanoi_disk_large", "hanoi_disk_medium", "hanoi_disk_small"]
    count = 0
    for have, want in zip(stack, target):
        if have != want:
            break
        count += 1
    return count


# ---------------------------------------------------------------- the table

# Per task: the sampler, the reference answers (keyed by our node or `node.output`), the
# priming of a prior (or None) and how the Rust side applies it.
TASKS = {
    "click_mouse": (_sample_click_mouse, _answer_click_mouse, None, None),
    "fold_glasses": (_sample_fold_glasses, _answer_fold_glasses, None, None),
    "pick_bucket": (_sample_pick_bucket, _answer_pick_bucket, None, None),
    "hammer_nail": (_sample_hammer_nail, _answer_hammer_nail, _prime_hammer_nail, "substep"),
    "pinch_tongs": (_sample_pinch_tongs, _answer_pinch_tongs, _prime_pinch_tongs, "step"),
    "water_plant": (_sample_water_plant, _answer_water_plant, _prime_water_plant, "step"),
    "bimanual_hanoi": (_sample_bimanual_hanoi, _answer_bimanual_hanoi, None, None),
    "bimanual_unlock_ipad": (
        _sample_bimanual_unlock_ipad,
        _answer_bimanual_unlock_ipad,
        None,
        None,
    ),
    "bimanual_assembly": (_sample_bimanual_assembly, _answer_bimanual_assembly, None, None),
    "bimanual_microwave_cook": (
        _sample_bimanual_microwave_cook,
        _answer_bimanual_microwave_cook,
        None,
        None,
    ),
    "bimanual_photograph": (_sample_bimanual_photograph, _answer_bimanual_photograph, None, None),
}


# Steps the Rust side evaluates each sample for: the Hanoi illegal verdict needs its state
# held for `_illegal_trigger_target` steps (the answer presets the counters to match).
STEPS = {"bimanual_hanoi": lambda u: int(u._illegal_trigger_target)}


def _state(u):
    out = np.zeros(mujoco.mj_stateSize(u._model, FULL))
    mujoco.mj_getState(u._model, u._data, out, FULL)
    return out


def run_task(task, samples, seed):
    """The states and the reference answers of one task."""
    config, env = ref.make_env(task, seed)
    u = env.unwrapped
    obs = u._compute_observation()["state"]
    state0 = np.concatenate(
        [np.asarray(obs[k], dtype=np.float64).ravel() for k in config.proprio_keys]
    )
    sample, answer, prime, prime_with = TASKS[task]
    reset = _state(u)
    rng = np.random.default_rng(seed)
    rows, answers, priors = [], {}, []
    for _ in range(samples):
        mujoco.mj_setState(u._model, u._data, reset, FULL)
        _forward(u)
        sample(u, rng)
        _forward(u)
        state = _state(u)
        prior = bool(prime and rng.random() < 0.5)
        primed, priming = None, np.zeros_like(reset)
        if prior:
            primed = prime(u, rng)
            _forward(u)
            priming = _state(u)
            mujoco.mj_setState(u._model, u._data, state, FULL)
            _forward(u)
        rows += [priming, state]
        for node, value in answer(u, prior, primed).items():
            answers.setdefault(node, []).append(float(value))
        priors.append(prior)
    env.close()
    blob = np.concatenate([state0, reset, *rows])
    meta = {
        "width": int(state0.size),
        "state_size": int(reset.size),
        "samples": samples,
        "disableflags": int(u._model.opt.disableflags),
        "nodes": answers,
        "prior": priors,
        "prime_with": prime_with,
        "steps": STEPS[task](u) if task in STEPS else 1,
    }
    return blob, meta


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--samples", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--tasks", default=",".join(TASKS))
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    manifest = {}
    for task in args.tasks.split(","):
        blob, meta = run_task(task, args.samples, args.seed)
        blob.astype("<f8").tofile(args.out / f"{task}.f64")
        manifest[task] = meta
    (args.out / "manifest.json").write_text(json.dumps(manifest))
    summary = {t: {n: sum(v) for n, v in m["nodes"].items()} for t, m in manifest.items()}
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
