"""Loads a LeRobot v3.0 dataset with Rerun's own LeRobot importer, as a user does with
`rerun <dataset>`, and reports what each recording holds (test venv, rerun-sdk):

    python rerun_import.py DATASET OUT.rrd

Runs `rerun --bind 127.0.0.1 --port P --save OUT.rrd DATASET` (the importer, no viewer),
then `rerun rrd print OUT.rrd` and groups its chunks by recording (each recording's
chunks start with its `/__properties` chunk). Prints JSON: the recordings' ids, and per
recording the rows of each entity's scalars, the video samples per camera, the task
text rows and the language rows per entity (`/language_persistent/<style>/<role>`).
"""

from __future__ import annotations

import json
import re
import socket
import subprocess
import sys
from pathlib import Path

CHUNK = re.compile(r"^Chunk\(\S+\) with (\d+) rows .* - (/\S+) - data columns: \[(.*)\]$")
RECORDING = re.compile(r'^\s+"(episode_\d+)",$')


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main(argv: list[str]) -> None:
    dataset, out = Path(argv[0]), Path(argv[1])
    rerun = Path(sys.executable).parent / "rerun"
    subprocess.run(
        [str(rerun), "--bind", "127.0.0.1", "--port", str(free_port()), "--save", str(out), str(dataset)],
        check=True,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        timeout=600,
    )
    printed = subprocess.run([str(rerun), "rrd", "print", str(out)], check=True, capture_output=True, text=True).stdout
    ids, recordings = [], []
    for line in printed.splitlines():
        if m := RECORDING.match(line):
            ids.append(m.group(1))
        m = CHUNK.match(line)
        if not m:
            continue
        rows, entity, columns = int(m.group(1)), m.group(2), m.group(3)
        if entity == "/__properties":
            recordings.append({"scalars": {}, "video_samples": {}, "task_rows": 0, "language": {}})
            continue
        rec = recordings[-1]
        if "Scalars:scalars" in columns:
            rec["scalars"][entity[1:]] = rec["scalars"].get(entity[1:], 0) + rows
        elif "VideoStream:sample" in columns:
            rec["video_samples"][entity[1:]] = rec["video_samples"].get(entity[1:], 0) + rows
        elif "TextDocument:text" in columns and entity.startswith("/language"):
            rec["language"][entity] = rec["language"].get(entity, 0) + rows
        elif "TextDocument:text" in columns:
            rec["task_rows"] += rows
    print(json.dumps({"recordings": ids, "contents": recordings}))


if __name__ == "__main__":
    main(sys.argv[1:])
