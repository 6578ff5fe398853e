"""Reads an MCAP file with the Python `mcap` library and prints JSON: the summary (schemas,
channels, message counts), the metadata records, and the decoded per-frame values of our
teleop schema (state rows, per-arm actions rebuilt from pose commands and hand targets).

usage: read_mcap.py FILE.mcap
"""
import json
import sys
from collections import defaultdict

from mcap.reader import make_reader


def main():
    with open(sys.argv[1], "rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        msgs = defaultdict(list)
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            msgs[channel.topic].append((message.sequence, json.loads(message.data)))
    out = {
        "profile": header.profile,
        "library": header.library,
        "schemas": sorted({s.name: s.encoding for s in summary.schemas.values()}.items()),
        "channels": {c.topic: {"schema": summary.schemas[c.schema_id].name, "encoding": c.message_encoding,
                               "metadata": dict(c.metadata)} for c in summary.channels.values()},
        "message_count": summary.statistics.message_count,
        "counts": {t: len(m) for t, m in msgs.items()},
        "metadata": metadata,
        "state": [m["values"] for _, m in msgs.get("/state", [])],
        "time": [m["time"] for _, m in msgs.get("/state", [])],
        "actions": {},
    }
    for topic, ms in msgs.items():
        if topic.endswith("/pose_command"):
            arm = topic.split("/")[1]
            hands = msgs[f"/{arm}/hand_target"]
            rows = []
            for (_, p), (_, h) in zip(ms, hands):
                pos, q = p["pose"]["position"], p["pose"]["orientation"]
                rows.append([pos["x"], pos["y"], pos["z"], q["w"], q["x"], q["y"], q["z"]] + h["position"])
            out["actions"][arm] = rows
    print(json.dumps(out))


if __name__ == "__main__":
    main()
