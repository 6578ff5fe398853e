"""Loads a state-only LeRobot v3.0 dataset with `observation.environment_state`
(`convert --environment-state`) with lerobot's own reader and prints, as JSON, the feature's
column names, its statistics' keys, every frame's values (float32 widened exactly) and whether
an ACT policy built from the dataset's metadata, with the environment state as its only
input beside the proprioception, takes a training step.

usage: lerobot_env_state.py ROOT
"""
import json
import os
import sys

os.environ["HF_HUB_OFFLINE"] = "1"
os.environ.setdefault("HF_DATASETS_OFFLINE", "1")

import torch  # noqa: E402
from lerobot.configs.types import FeatureType  # noqa: E402
from lerobot.datasets.lerobot_dataset import LeRobotDataset  # noqa: E402
from lerobot.utils.feature_utils import dataset_to_policy_features  # noqa: E402
from lerobot.policies.act.configuration_act import ACTConfig  # noqa: E402
from lerobot.policies.act.modeling_act import ACTPolicy  # noqa: E402

KEY = "observation.environment_state"
root = sys.argv[1]
ds = LeRobotDataset("local/dexjoco-env-state", root=root)
feature = ds.meta.features[KEY]
values = [[float(x) for x in ds[i][KEY]] for i in range(len(ds))]
stats = ds.meta.stats[KEY]
assert set(stats) >= {"min", "max", "mean", "std", "count"}, stats.keys()
assert len(stats["mean"]) == feature["shape"][0]

features = dataset_to_policy_features(ds.meta.features)
inputs = {k: f for k, f in features.items() if f.type is not FeatureType.ACTION}
outputs = {k: f for k, f in features.items() if f.type is FeatureType.ACTION}
assert set(inputs) == {"observation.state", KEY}, sorted(inputs)
config = ACTConfig(input_features=inputs, output_features=outputs, chunk_size=5, n_action_steps=5,
                   dim_model=32, dim_feedforward=64, n_encoder_layers=1, n_decoder_layers=1, n_heads=2,
                   use_vae=False, device="cpu")
policy = ACTPolicy(config)
assert policy.config.env_state_feature is not None
batch = {k: torch.stack([torch.as_tensor(ds[i][k]) for i in range(4)]) for k in ("observation.state", KEY)}
batch["action"] = torch.stack([torch.as_tensor(ds[i]["action"]) for i in range(4)]).unsqueeze(1).repeat(1, 5, 1)
batch["action_is_pad"] = torch.zeros(4, 5, dtype=torch.bool)
loss, _ = policy.forward(batch)
loss.backward()
print(json.dumps({
    "names": feature["names"],
    "stats_keys": sorted(stats),
    "environment_state": values,
    "act_trained": bool(torch.isfinite(loss).item()),
}))
