"""Prints the frames of each episode of a LeRobot dataset, counted from its data files
(not its metadata), as JSON: {"lengths": [...]}.

usage: episode_lengths.py ROOT
"""
import json
import sys
from pathlib import Path

import pandas as pd

root = Path(sys.argv[1])
frames = pd.concat([pd.read_parquet(f) for f in sorted(root.glob("data/**/*.parquet"))])
episodes = sorted(frames["episode_index"].unique())
lengths = [int((frames["episode_index"] == e).sum()) for e in episodes]
print(json.dumps({"lengths": lengths}))
