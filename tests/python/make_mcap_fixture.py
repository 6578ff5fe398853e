"""Writes one teleop episode as MCAP with the Python `mcap` library, following our schema
(schemas/mcap-teleop.md): the `dexjoco.episode` metadata record, per-arm
`/<arm>/pose_command` (foxglove.PoseInFrame) and `/<arm>/hand_target`
(dexjoco.HandJointTargets), `/state` (dexjoco.State), optionally `/action_rotvec`,
raw teleop streams and a foxglove.CompressedImage camera. JSON encoding, zstd chunks.

Prints the episode's arrays as JSON, as make_raw_fixture.py does.

usage: make_mcap_fixture.py OUT.mcap TASK FRAMES SEED [--no-rotvec] [--extras] [--nan]
"""
import base64
import json
import os
import sys

from mcap.writer import CompressionType, Writer

from dexjoco_fixture_data import TASKS, make_arrays

SCHEMAS = os.path.join(os.path.dirname(__file__), "..", "..", "schemas", "mcap")


def schema(w, name):
    with open(os.path.join(SCHEMAS, f"{name}.json"), "rb") as f:
        return w.register_schema(name=name, encoding="jsonschema", data=f.read())


def stamp(t):
    sec = int(t)
    return {"sec": sec, "nsec": min(999_999_999, round((t - sec) * 1e9))}


def joint_order(arm):
    fingers = ["rf", "mf", "ff", "th"] if arm == "left" else ["ff", "mf", "rf", "th"]
    return ",".join(f"{f}{j}" for f in fingers for j in range(4))


def main():
    out, task, frames, seed = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    flags = set(sys.argv[5:])
    arrays = make_arrays(task, frames, seed)
    if "--no-rotvec" in flags:
        del arrays["action_rotvec"]
    if "--nan" in flags:
        arrays["state"][frames // 2, 3] = float("nan")
    arms = ["arm"] if TASKS[task][0] == 1 else ["right", "left"]
    with open(out, "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile="", library="dexjoco-data tests (python mcap)")
        w.add_metadata("dexjoco.episode", {
            "schema_version": "1", "task": task, "fps": "30",
            "setup": "single_arm" if len(arms) == 1 else "bimanual",
            "operator": "fixture", "date": "2026-01-02T03:04:05Z", "rig": "vision-pro",
        })
        pose_s, hand_s, state_s = schema(w, "foxglove.PoseInFrame"), schema(w, "dexjoco.HandJointTargets"), schema(w, "dexjoco.State")
        chans = []
        for arm in arms:
            p = w.register_channel(f"/{arm}/pose_command", "json", pose_s)
            h = w.register_channel(f"/{arm}/hand_target", "json", hand_s, {"joint_order": joint_order(arm)})
            chans.append((p, h))
        st = w.register_channel("/state", "json", state_s)
        rv = None
        if "action_rotvec" in arrays:
            rv = w.register_channel("/action_rotvec", "json", schema(w, "dexjoco.ActionRotvec"))
        extras = "--extras" in flags
        if extras:
            wrist = w.register_channel("/teleop/right/wrist_pose", "json", pose_s)
            tips = w.register_channel("/teleop/right/fingertips", "json", schema(w, "dexjoco.Keypoints"))
            cam = w.register_channel("/camera/front/image", "json", schema(w, "foxglove.CompressedImage"))

        def put(ch, k, t, msg):
            ns = round(t * 1e9)
            w.add_message(ch, log_time=ns, publish_time=ns, sequence=k,
                          data=json.dumps(msg, allow_nan=True).encode())

        act, state, ts = arrays["action"], arrays["state"], arrays["timestamp"]
        for k in range(frames):
            t = float(ts[k])
            for i, (p, h) in enumerate(chans):
                a = act[k, 23 * i:23 * (i + 1)]
                put(p, k, t, {"timestamp": stamp(t), "frame_id": "world", "pose": {
                    "position": {"x": a[0], "y": a[1], "z": a[2]},
                    "orientation": {"x": a[4], "y": a[5], "z": a[6], "w": a[3]}}})
                put(h, k, t, {"timestamp": stamp(t), "frame": k, "position": [float(x) for x in a[7:]]})
            put(st, k, t, {"timestamp": stamp(t), "frame": k, "time": t, "values": [float(x) for x in state[k]]})
            if rv is not None:
                put(rv, k, t, {"timestamp": stamp(t), "frame": k, "values": [float(x) for x in arrays["action_rotvec"][k]]})
            if extras:
                put(wrist, k, t, {"timestamp": stamp(t), "frame_id": "tracker", "pose": {
                    "position": {"x": 0.1, "y": 0.2, "z": 0.3}, "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}}})
                put(tips, k, t, {"timestamp": stamp(t), "frame_id": "tracker", "names": ["thumb_tip", "index_tip"],
                                 "points": [{"x": 0.01, "y": 0, "z": 0}, {"x": 0, "y": 0.02, "z": 0}]})
                if k % 10 == 0:
                    put(cam, k, t, {"timestamp": stamp(t), "frame_id": "front", "format": "png",
                                    "data": base64.b64encode(b"\x89PNG fake").decode()})
        w.finish()
    print(json.dumps({name: {"shape": list(a.shape), "dtype": str(a.dtype),
                             "values": [float(x) for x in a.ravel()]} for name, a in arrays.items()}))


if __name__ == "__main__":
    main()
