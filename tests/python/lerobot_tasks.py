"""Reads a LeRobot v3.0 dataset with lerobot's own reader (offline, root=) and prints, as
JSON, its task table (task_index -> text) and the task text of every frame (from the
frames' task_index), without decoding videos.

usage: lerobot_tasks.py ROOT
"""
import json
import os
import sys

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

from lerobot.datasets.lerobot_dataset import LeRobotDataset  # noqa: E402

ds = LeRobotDataset("local/dexjoco-test", root=sys.argv[1])
by_index = {int(i): str(t) for t, i in zip(ds.meta.tasks.index, ds.meta.tasks["task_index"])}
frames = [by_index[int(i)] for i in ds.hf_dataset["task_index"]]
print(json.dumps({"tasks": by_index, "frames": frames}))
