"""Converts a LeRobot v2.1 dataset to v3.0 in place with lerobot 0.6.1's own script
(lerobot/scripts/convert_dataset_v21_to_v30.py), offline: a local root, no hub push.

usage: lerobot_v21_to_v30.py ROOT
Prints {"hf_features": the `huggingface` schema metadata of episode 0's parquet, as
datasets' Features reads it back; "hf_types": each feature's datasets type} after the
conversion ran; the v2.1 original is left at ROOT_old.
"""
import json
import os
import sys

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

from lerobot.scripts.convert_dataset_v21_to_v30 import convert_dataset  # noqa: E402

import datasets  # noqa: E402
import pyarrow.parquet as pq  # noqa: E402

root = sys.argv[1]
schema = pq.read_schema(f"{root}/data/chunk-000/episode_000000.parquet")
hf = json.loads(schema.metadata[b"huggingface"])["info"]["features"]
features = datasets.Features.from_arrow_schema(schema)
types = {k: type(v).__name__ for k, v in features.items()}
convert_dataset("local/dexjoco-v21", root=root, push_to_hub=False)
print(json.dumps({"hf_features": hf, "hf_types": types}))
