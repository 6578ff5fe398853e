"""openpi's own normalization statistics of a LeRobot dataset, for `convert --norm-stats`.

Usage: openpi_norm_stats.py OPENPI_SRC DATASET_ROOT OURS_DIR HORIZON BATCH

OPENPI_SRC is openpi's `src` folder (the reference copy, imported in place); its
`openpi/shared/normalize.py` gives `RunningStats`, `save`, `load` and `serialize_json`.
The dataset is fed as openpi's `scripts/compute_norm_stats.py` feeds it: lerobot's
`LeRobotDataset` with `delta_timestamps` of HORIZON frames for `action` (lerobot repeats
an episode's last frame past its end), a torch `DataLoader` of BATCH items in dataset
order with `drop_last` for `len(dataset) // BATCH` batches (openpi's `TorchDataLoader`
without shuffling), items stacked as numpy arrays, `observation.state` as `state` and
`action` as `actions`, one `RunningStats.update` per batch and key.

Prints JSON: `frames`, `batches`, the batches' `dtype`, the `numpy` version, `float32`
(the statistics of the batches as the loader gives them: float32), `float64` (the same
batches widened to float64), `openpi_file` (the text `normalize.save` writes for the
float32 statistics) and `ours_reserialized` (OURS_DIR's `norm_stats.json` read by
`normalize.load` and written back by `serialize_json`).
"""

import json
import os
import pathlib
import sys
import tempfile

import numpy as np

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

import torch  # noqa: E402
from lerobot.datasets.lerobot_dataset import LeRobotDataset, LeRobotDatasetMetadata  # noqa: E402

REPO_ID = "local/dexjoco-norm-stats"
KEYS = {"state": "observation.state", "actions": "action"}


def stack(items):
    """openpi's collate: each key's values stacked into one numpy array."""
    return {key: np.stack([np.asarray(item[src]) for item in items]) for key, src in KEYS.items()}


def statistics(stats):
    """`{key: {mean, std, q01, q99}}` as lists of floats."""
    out = {}
    for key, running in stats.items():
        s = running.get_statistics()
        out[key] = {name: np.asarray(getattr(s, name)).tolist() for name in ("mean", "std", "q01", "q99")}
    return out


def main():
    openpi_src, root, ours_dir, horizon, batch_size = sys.argv[1:6]
    horizon, batch_size = int(horizon), int(batch_size)
    sys.dont_write_bytecode = True  # nothing written into the reference copy
    sys.path.insert(0, openpi_src)
    from openpi.shared import normalize

    fps = LeRobotDatasetMetadata(REPO_ID, root=root).fps
    dataset = LeRobotDataset(
        REPO_ID, root=root, delta_timestamps={"action": [t / fps for t in range(horizon)]}
    )
    num_batches = len(dataset) // batch_size
    loader = torch.utils.data.DataLoader(
        dataset, batch_size=batch_size, shuffle=False, drop_last=True, collate_fn=stack
    )
    as_loaded = {key: normalize.RunningStats() for key in KEYS}
    widened = {key: normalize.RunningStats() for key in KEYS}
    for _, batch in zip(range(num_batches), loader):
        for key in KEYS:
            as_loaded[key].update(batch[key])
            widened[key].update(batch[key].astype(np.float64))

    with tempfile.TemporaryDirectory() as tmp:
        normalize.save(tmp, {key: s.get_statistics() for key, s in as_loaded.items()})
        openpi_file = (pathlib.Path(tmp) / "norm_stats.json").read_text()
    print(
        json.dumps(
            {
                "frames": len(dataset),
                "batches": num_batches,
                "dtype": str(batch["state"].dtype),
                "numpy": np.__version__,
                "float32": statistics(as_loaded),
                "float64": statistics(widened),
                "openpi_file": openpi_file,
                "ours_reserialized": normalize.serialize_json(normalize.load(ours_dir)),
            }
        )
    )


if __name__ == "__main__":
    main()
