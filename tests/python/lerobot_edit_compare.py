"""Compares an edited LeRobot v3.0 dataset with its source, with lerobot's own reader:
every kept episode's frames (all numeric columns and the task text) equal the source's,
in order; each camera frame decodes to the source's (bit for bit with --exact-video,
else within a mean error of 3 levels, for re-encoded files); statistics equal a numpy
computation from every frame (min, max, mean, std) and lerobot's get_feature_stats
(quantiles).
Prints a JSON report; exits 1 on the first difference, naming it.

usage: lerobot_edit_compare.py SOURCE EDITED KEPT [--exact-video] [--columns] [--stats-report]
                               [--offset N] [--rename OLD=NEW] [--removed KEY] [--stats-only]
  KEPT: the source episode indices the edited dataset holds, in its order (JSON list)
  --columns: also compare every per-episode column but the placement ones
  --stats-report: report the statistics' differences without failing on them
  --offset N: the kept episodes start at episode N of EDITED (a merge's later source)
  --rename OLD=NEW: the source's feature OLD is NEW in EDITED
  --removed KEY: EDITED has left out feature KEY (its per-episode columns too)
  --stats-only: only EDITED's statistics against its own frames (KEPT unused)
  --frames JSON: EDITED's episode i holds frames FROM..TO of its source episode, for the
                 episodes named ({"i": [FROM, TO]}; a trim): frame_index and timestamp
                 count from 0 there, and their per-episode statistics are not compared
A numeric column wider in EDITED than in SOURCE must hold the source's values then zeros
(a merge's padding). Statistics are checked without --offset only.
"""
import json
import os
import sys

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from lerobot.datasets.compute_stats import get_feature_stats  # noqa: E402
from lerobot.datasets.lerobot_dataset import LeRobotDataset  # noqa: E402

source, edited, kept = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
exact_video = "--exact-video" in sys.argv
columns = "--columns" in sys.argv
stats_report = "--stats-report" in sys.argv  # report statistics differences, never fail on them
def flag(name, default):
    return sys.argv[sys.argv.index(name) + 1] if name in sys.argv else default


offset = int(flag("--offset", "0"))
rename = dict([flag("--rename", "=").split("=", 1)]) if "--rename" in sys.argv else {}
removed = flag("--removed", None)
trims = {int(k): v for k, v in json.loads(flag("--frames", "{}")).items()}
src = LeRobotDataset("local/src", root=source, video_backend="pyav")
out = LeRobotDataset("local/out", root=edited, video_backend="pyav")


def fail(msg):
    print(json.dumps({"ok": False, "error": msg}))
    sys.exit(1)


stats_only = "--stats-only" in sys.argv
if stats_only:
    kept = []
elif out.num_episodes < offset + len(kept) or (offset == 0 and out.num_episodes != len(kept) and "--offset" not in sys.argv):
    fail(f"{out.num_episodes} episodes, expected {len(kept)}")


def episode_range(ds, e):
    ep = ds.meta.episodes[e]
    return int(ep["dataset_from_index"]), int(ep["dataset_to_index"])


numeric = [k for k, f in src.meta.features.items() if f["dtype"] in ("float32", "float64")]
video_diffs = []
exact_frames = 0
frames = 0
for new, old in enumerate(kept):
    new += offset
    a0, a1 = episode_range(src, old)
    b0, b1 = episode_range(out, new)
    shift = 0
    if new in trims:
        shift = trims[new][0]
        a0, a1 = a0 + trims[new][0], a0 + trims[new][1]
    if a1 - a0 != b1 - b0:
        fail(f"episode {new} (source {old}): {b1 - b0} frames, source {a1 - a0}")
    for k in range(a1 - a0):
        x, y = src[a0 + k], out[b0 + k]
        frames += 1
        if int(y["episode_index"]) != new or int(y["index"]) != b0 + k:
            fail(f"episode {new} frame {k}: episode_index/index {int(y['episode_index'])}/{int(y['index'])}")
        if int(y["frame_index"]) != int(x["frame_index"]) - shift or y["task"] != x["task"]:
            fail(f"episode {new} frame {k}: frame_index or task differs")
        if abs(float(y["timestamp"]) - (float(x["timestamp"]) - shift / src.fps)) > 1e-4:
            fail(f"episode {new} frame {k}: timestamp {float(y['timestamp'])}, source {float(x['timestamp'])} - {shift} frames")
        for key in (k for k in numeric if k != "timestamp"):
            xa, ya = np.atleast_1d(np.asarray(x[key])), np.atleast_1d(np.asarray(y[rename.get(key, key)]))
            if ya.shape[0] > xa.shape[0] and not ya[xa.shape[0]:].any():
                ya = ya[: xa.shape[0]]  # zero-padded by a merge
            if not np.array_equal(xa, ya):
                fail(f"episode {new} frame {k}: {key} differs")
        for key in src.meta.camera_keys:
            d = np.abs(np.asarray(x[key], dtype=np.float64) - np.asarray(y[rename.get(key, key)], dtype=np.float64)) * 255.0
            video_diffs.append(float(d.mean()))
            exact_frames += int(d.max() == 0)
            if exact_video and d.max() > 0:
                fail(f"episode {new} frame {k}: {key} decodes differently (max {d.max():.1f} levels)")
if video_diffs and max(video_diffs) > 3.0:
    fail(f"video frames differ by up to {max(video_diffs):.2f} levels on average")

# Statistics against every frame's values.
hf = out.hf_dataset.with_format("numpy")
stats_check = {}
for key in (numeric if offset == 0 and not rename else []):
    v = np.stack(hf[key]).astype(np.float64)
    s = out.meta.stats[key]
    for name, want in [("min", v.min(0)), ("max", v.max(0)), ("mean", v.mean(0)), ("std", v.std(0))]:
        got = np.asarray(s[name], dtype=np.float64).reshape(want.shape)
        err = float(np.abs(got - want).max())
        stats_check[f"{key}/{name}"] = err
        if err > 1e-5 * max(1.0, float(np.abs(want).max())) and not stats_report:
            fail(f"stats {key} {name}: off by {err}")
    # Quantiles as lerobot's own get_feature_stats computes them from these frames.
    theirs = get_feature_stats(v, axis=0, keepdims=False)
    for q in ("q01", "q10", "q50", "q90", "q99"):
        if q in s and q in theirs:
            got = np.asarray(s[q], dtype=np.float64).reshape(theirs[q].shape)
            err = float(np.abs(got - theirs[q]).max())
            stats_check[f"{key}/{q}"] = err
            if err > 1e-5 * max(1.0, float(np.abs(v).max())) and not stats_report:
                fail(f"stats {key} {q}: off by {err} from lerobot's get_feature_stats")



def same_value(x, y):
    """Equal values; numbers (and arrays of them) to 1e-9, as recomputed statistics."""
    try:
        fx = np.asarray(x, dtype=np.float64)
        fy = np.asarray(y, dtype=np.float64)
        return fx.shape == fy.shape and np.allclose(fx, fy, rtol=1e-9, atol=1e-9, equal_nan=True)
    except (TypeError, ValueError):
        return str(x) == str(y)


if columns:
    def rows(root):
        files = sorted(p for p in __import__("pathlib").Path(root, "meta/episodes").rglob("*.parquet"))
        return pd.concat([pd.read_parquet(f) for f in files]).sort_values("episode_index").reset_index(drop=True)
    placement = ("episode_index", "data/", "dataset_from_index", "dataset_to_index", "meta/episodes/", "videos/")
    # Renumbered by the edit: their per-episode statistics must describe the new numbers.
    renumbered = ("stats/episode_index/", "stats/index/", "stats/task_index/")
    a, b = rows(source), rows(edited)
    for new, old in enumerate(kept):
        new += offset
        b0, b1 = episode_range(out, new)
        for c, want in [("stats/episode_index/min", new), ("stats/episode_index/max", new),
                        ("stats/index/min", b0), ("stats/index/max", b1 - 1)]:
            if c in b.columns and not same_value(b[c][new], [want]):
                fail(f"per-episode column {c}, episode {new}: {b[c][new]!r}, expected [{want}]")
    # A trimmed episode's per-episode statistics describe its kept frames.
    for new in trims:
        b0, b1 = episode_range(out, new)
        for key in numeric:
            v = np.stack(hf[key][b0:b1]).astype(np.float64).reshape(b1 - b0, -1)
            for name, want in [("min", v.min(0)), ("max", v.max(0)), ("mean", v.mean(0))]:
                c = f"stats/{key}/{name}"
                if c in b.columns and not np.allclose(np.asarray(b[c][new], dtype=np.float64).ravel(), want, atol=1e-6):
                    fail(f"per-episode column {c}, trimmed episode {new}: {b[c][new]!r}, its frames give {want}")
    for c in a.columns:
        if c.startswith(placement) or c.startswith(renumbered):
            continue
        if removed and (c.startswith(f"stats/{removed}/") or c.startswith(f"videos/{removed}/")):
            if c in b.columns:
                fail(f"per-episode column {c} of the removed feature is still there")
            continue
        bc = c
        for was, now in rename.items():
            bc = bc.replace(f"/{was}/", f"/{now}/")
        if bc not in b.columns:
            fail(f"per-episode column {c} is gone")
        for new, old in enumerate(kept):
            new += offset
            if new in trims and (c.startswith("stats/") or c == "length"):
                continue  # recomputed for the kept frames
            if not same_value(a[c][old], b[bc][new]):
                fail(f"per-episode column {c}, episode {new}: {b[bc][new]!r} != source {a[c][old]!r}")

print(json.dumps({
    "ok": True,
    "episodes": out.num_episodes,
    "frames": frames,
    "video_mean_error_max": max(video_diffs) if video_diffs else None,
    "video_frames": len(video_diffs),
    "video_frames_exact": exact_frames,
    "stats": stats_check,
}))
