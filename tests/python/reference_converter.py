"""The DexJoCo reference converter (`dexjoco-data-converter`), run in place, and a
description of converted datasets for comparing it with `dexjoco-data convert`.

Runs in the readers' venv (lerobot 0.6.1, zarr 2, tyro, imageio[ffmpeg]). The reference
code is imported where it lies (never copied): `--code` is the reference converter's
`src/` folder, `--diffusion-policy` the folder holding Diffusion Policy's
`diffusion_policy/common/replay_buffer.py` (the reference's zarr writer imports it).

usage:
  reference_converter.py run --code SRC --diffusion-policy DP [--configs DIR --task T]
                             ENTRY_POINT ARGS...
      ENTRY_POINT is one of the reference's console scripts (its pyproject.toml), e.g.
      dexjoco-dc-single-lerobot / dexjoco-dc-single-zarr; ARGS are that command's own
      flags, parsed by its own tyro CLI. With --configs (a reference config folder such
      as converter-configs/rand_full) the single-dataset flags come from its files,
      task T's entry of each, as the reference's batch commands take them:
      --slice-yaml from slice_config.yaml, and for the LeRobot one also
      --language-instruction and --selected-data-yaml.
  reference_converter.py describe --diffusion-policy DP --lerobot ROOT... --zarr ROOT...
      Prints JSON {ROOT: description}: for a LeRobot dataset (read with lerobot's
      LeRobotDataset, offline, pyav) its info, camera keys, tasks, per-episode lengths,
      tasks, action / observation.state (float32), and per camera the frames pyav
      decodes inside the episode's timestamps; for a Diffusion Policy output (read with
      Diffusion Policy's ReplayBuffer) its arrays (dtype, shape, chunks, compressor,
      values), episode ends, and each episode video's decoded frames with the camera ->
      file map. A frame is described by its 8x8 thumbnail (grey levels, block means), so
      that frames of two encodings of one video can be matched.

Adaptation to lerobot 0.6.1: none is needed. The reference's LeRobot writer runs as it
is (`LeRobotDataset.create(..., streaming_encoding=True, encoder_queue_maxsize=0)` exist
in 0.6.1); it never calls `finalize()`, and the dataset it leaves still loads in 0.6.1
(the parity test loads it).
"""

import json
import os
import sys
from pathlib import Path

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

# The reference's console scripts (dexjoco-data-converter/pyproject.toml) -> cli.py names.
ENTRY_POINTS = {
    "dexjoco-dc-single-lerobot": "single_lerobot_cli",
    "dexjoco-dc-single-zarr": "single_zarr_cli",
    "dexjoco-dc-batch-lerobot": "batch_lerobot_cli",
    "dexjoco-dc-batch-zarr": "batch_zarr_cli",
    "dexjoco-dc-merge-lerobot": "merge_lerobot_cli",
    "dexjoco-dc-merge-zarr": "merge_zarr_cli",
}


def take_option(args, name):
    """Removes every `name VALUE` pair from `args`; returns the values."""
    values = []
    while name in args:
        i = args.index(name)
        values.append(args[i + 1])
        del args[i : i + 2]
    return values


def config_flags(entry, configs, task):
    """The single-dataset flags for task `task` from a reference config folder."""
    import yaml

    def entry_of(name):
        return yaml.safe_load((Path(configs) / name).read_text())[task]

    def flow(value):
        return yaml.safe_dump(value, default_flow_style=True, sort_keys=False, width=10**6).strip()

    flags = ["--slice-yaml", flow(entry_of("slice_config.yaml"))]
    if entry.endswith("-lerobot"):
        flags += ["--language-instruction", entry_of("language_instructions.yaml"),
                  "--selected-data-yaml", flow(entry_of("selected_data.yaml"))]
    return flags


def run(args):
    """Runs one reference console script with its own argument parser."""
    (code,) = take_option(args, "--code")
    (dp,) = take_option(args, "--diffusion-policy")
    configs, task = take_option(args, "--configs"), take_option(args, "--task")
    sys.path[:0] = [code, dp]
    from dexjoco_data_converter import cli

    entry = args.pop(0)
    if configs:
        args += config_flags(entry, configs[0], task[0])
    sys.argv = [entry, *args]
    getattr(cli, ENTRY_POINTS[entry])()


def thumbnails(path, from_s=None, to_s=None):
    """Decodes a video with pyav; the 8x8 grey thumbnail (64 block means, row-major) of
    each frame whose time lies in [from_s, to_s) (half a frame early, as timestamps are
    k / fps), or of every frame."""
    import av

    out = []
    with av.open(str(path)) as c:
        stream = c.streams.video[0]
        half = 0.5 / float(stream.average_rate or 30)
        for f in c.decode(stream):
            t = float(f.time)
            if from_s is not None and not (from_s - half <= t < to_s - half):
                continue
            grey = f.to_ndarray(format="rgb24").mean(axis=2)
            h, w = grey.shape[0] // 8, grey.shape[1] // 8
            blocks = grey[: 8 * h, : 8 * w].reshape(8, h, 8, w).mean(axis=(1, 3))
            out.append([round(float(v), 2) for v in blocks.ravel()])
    return out


def describe_lerobot(root):
    """What a LeRobot v3.0 dataset holds, read by lerobot itself."""
    import numpy as np
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    ds = LeRobotDataset("local/parity", root=root, video_backend="pyav")
    meta = ds.meta
    data = ds.hf_dataset.with_format("numpy")
    ep_col = np.asarray(data["episode_index"])
    action = np.stack(data["action"]).astype(np.float32)
    state = np.stack(data["observation.state"]).astype(np.float32)
    task_index = np.asarray(data["task_index"])
    tasks_by_index = {int(i): t for t, i in zip(meta.tasks.index, meta.tasks["task_index"])}
    episodes = []
    for ep in meta.episodes:
        i = int(ep["episode_index"])
        rows = np.flatnonzero(ep_col == i)
        videos = {}
        for key in meta.video_keys:
            path = Path(root) / meta.get_video_file_path(i, key)
            videos[key] = thumbnails(path, ep[f"videos/{key}/from_timestamp"], ep[f"videos/{key}/to_timestamp"])
        # lerobot's own frame lookup (timestamp tolerance checked) at both ends.
        first, last = ds[int(rows[0])], ds[int(rows[-1])]
        episodes.append({
            "index": i,
            "length": int(ep["length"]),
            "rows": len(rows),
            "tasks": list(ep["tasks"]),
            "frame_tasks": sorted({tasks_by_index[int(t)] for t in task_index[rows]}),
            "first_last_task": [first["task"], last["task"]],
            "action": action[rows].tolist(),
            "state": state[rows].tolist(),
            "videos": videos,
        })
    features = {
        k: {"dtype": v["dtype"], "shape": list(v["shape"]), "codec": (v.get("info") or {}).get("video.codec")}
        for k, v in meta.features.items()
    }
    return {
        "fps": meta.fps,
        "robot_type": meta.robot_type,
        "features": features,
        "camera_keys": sorted(meta.video_keys),
        "tasks": sorted(meta.tasks.index),
        "episodes": episodes,
    }


def camera_files(root):
    """Camera -> file name in each episode's video folder: the reference's
    video_name_map.yaml ({"front.mp4": "0.mp4"}) or our name_map.json."""
    import yaml

    ref = root / "video_name_map.yaml"
    if ref.is_file():
        return {Path(k).stem: v for k, v in yaml.safe_load(ref.read_text()).items()}
    ours = json.loads((root / "videos/name_map.json").read_text())
    return {name: f"{i}.mp4" for i, name in enumerate(ours["cameras"])}


def describe_zarr(root, dp):
    """What a Diffusion Policy output holds, read by Diffusion Policy's ReplayBuffer."""
    sys.path.insert(0, dp)
    from diffusion_policy.common.replay_buffer import ReplayBuffer

    root = Path(root)
    rb = ReplayBuffer.create_from_path(str(root / "replay_buffer.zarr"), mode="r")
    arrays = {}
    for key, arr in rb.items():
        a = {"dtype": str(arr.dtype), "shape": list(arr.shape), "chunks": list(arr.chunks),
             "compressor": repr(arr.compressor)}
        if arr.ndim <= 2:
            a["values"] = arr[:].tolist()
        arrays[key] = a
    files = camera_files(root)
    videos = [
        {cam: thumbnails(root / "videos" / str(e) / name) for cam, name in files.items()}
        for e in range(rb.n_episodes)
    ]
    return {
        "episode_ends": [int(x) for x in rb.episode_ends[:]],
        "arrays": arrays,
        "camera_files": files,
        "videos": videos,
    }


def describe(args):
    """Prints the description of every --lerobot and --zarr dataset."""
    (dp,) = take_option(args, "--diffusion-policy")
    out = {p: describe_lerobot(p) for p in take_option(args, "--lerobot")}
    out.update({p: describe_zarr(p, dp) for p in take_option(args, "--zarr")})
    assert not args, f"unknown arguments {args}"
    print(json.dumps(out))


if __name__ == "__main__":
    command, rest = sys.argv[1], sys.argv[2:]
    {"run": run, "describe": describe}[command](rest)
