#!/usr/bin/env python3
"""Serve a trained LeRobot policy to ``dexjoco-data eval`` through openpi's websocket server.

``dexjoco-data eval`` speaks openpi's websocket protocol: the server sends its metadata
first, then answers every observation

    {<policy image key>: uint8 (224, 224, 3), ..., "state": float64 (23,) or (46,),
     "prompt": str, ["environment_state": float64 with eval --environment-state],
     ["dexjoco/...": extra keys, ignored here]}

with ``{"actions": (chunk_len, 22 or 44)}`` (per arm: xyz, rotation vector, 16 hand joints).
This script loads a LeRobot checkpoint folder (the ``pretrained_model`` folder that
``lerobot-train`` writes: config.json, model.safetensors and the processor pipelines
policy_preprocessor.json / policy_postprocessor.json with their normalization stats), wraps
it in a ``.infer(obs)`` policy and serves it with openpi's ``WebsocketPolicyServer``.

Per observation it does what LeRobot does at inference:

1. maps eval's image keys to the policy's image features (``--camera``), converts them
   with ``lerobot.policies.prepare_observation_for_inference`` (uint8 HWC -> float32 CHW in
   [0, 1], batch dimension) and resizes them (bilinear, antialiased) to the feature shape
   the policy was trained on (eval always sends 224x224);
2. runs the checkpoint's own preprocessor pipeline (normalization with the training stats);
3. asks the policy for a whole action chunk (``policy.predict_action_chunk``, not
   ``select_action``: ACT returns ``chunk_size`` actions, Diffusion Policy its
   ``n_action_steps``);
4. runs the checkpoint's postprocessor on each action of the chunk (unnormalization), as
   lerobot's own async policy server does, and returns ``(chunk_len, action_dim)`` float32.

The server is stateless: every request is answered from that observation alone (the
policy is reset before each chunk), so several eval workers (``eval -j N``) can share it.
A policy with ``n_obs_steps > 1`` (Diffusion Policy's default is 2) sees the current
observation repeated ``n_obs_steps`` times, which is what LeRobot feeds it on the first step
of an episode; eval asks for a chunk only every few steps, so no true history is kept.

Any policy type registered in lerobot (``act``, ``diffusion``, ...) loads the same way
(``lerobot.policies.get_policy_class`` on the ``type`` in config.json); Diffusion Policy
needs lerobot's ``diffusers`` extra installed.

Requirements (in the lerobot 0.6.1 environment):
    pip install --no-deps openpi-client==0.1.2   # only msgpack_numpy/base_policy are used
    pip install websockets==17.4 msgpack==1.2.4
and openpi's source tree for ``openpi.serving.websocket_policy_server`` (``--openpi-src``).

Usage:
    # serve (cameras: eval's key = the dataset's image feature; repeat per camera)
    python examples/serve_lerobot_policy.py \\
        --checkpoint outputs/train/act/checkpoints/last/pretrained_model \\
        --camera base=observation.images.third_person \\
        --camera wrist=observation.images.handcam_rgb --port 8000

    # in another shell: evaluate it
    dexjoco-data eval --task click_mouse --episodes 10 --rand-full \\
        --host 127.0.0.1 --port 8000 --render-size 96x96 --quality fast --no-videos

Without ``--camera`` an eval key ``k`` goes to the feature ``observation.images.k``; a
feature with no camera is an error at start-up, naming the keys eval sends for the task
(``--task``'s first camera is ``base``, its wrist camera ``wrist``). ``--camera
base=third_person`` is short for ``base=observation.images.third_person``. At start-up
one dummy observation is run through the whole pipeline, so a broken checkpoint or mapping
fails before eval connects.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

LOG = logging.getLogger("serve_lerobot_policy")

REPO_ROOT = Path(__file__).resolve().parents[1]
DEFAULT_OPENPI_SRC = REPO_ROOT.parent / "shared" / "third_party" / "dexjoco-8d23b0f" / "openpi" / "src"
IMAGE_PREFIX = "observation.images."
STATE_KEY = "observation.state"
ENV_KEY = "observation.environment_state"  # eval sends it as environment_state (--environment-state)
EVAL_IMAGE_SIZE = 224  # eval pads and resizes every camera to 224x224


def parse_camera_map(values: list[str]) -> dict[str, str]:
    """``["base=observation.images.x", "wrist=y"]`` -> ``{"base": "observation.images.x", "wrist": "observation.images.y"}``."""
    mapping: dict[str, str] = {}
    for value in values:
        eval_key, sep, feature = value.partition("=")
        eval_key, feature = eval_key.strip(), feature.strip()
        if not sep or not eval_key or not feature:
            raise SystemExit(f"--camera {value!r}: expected EVAL_KEY=FEATURE, e.g. base=observation.images.third_person")
        if not feature.startswith("observation."):
            feature = IMAGE_PREFIX + feature
        if eval_key in mapping:
            raise SystemExit(f"--camera: eval key {eval_key!r} given twice")
        mapping[eval_key] = feature
    return mapping


def import_openpi_server(openpi_src: Path):
    """Import ``openpi.serving.websocket_policy_server`` from openpi's source tree."""
    server_file = openpi_src / "openpi" / "serving" / "websocket_policy_server.py"
    if not server_file.is_file():
        raise SystemExit(
            f"openpi's websocket server not found: {server_file} does not exist.\n"
            "Give --openpi-src the `src` folder of an openpi checkout "
            "(the one holding openpi/serving/websocket_policy_server.py)."
        )
    missing = []
    for module in ("openpi_client", "websockets", "msgpack"):
        try:
            __import__(module)
        except ImportError:
            missing.append(module)
    if missing:
        raise SystemExit(
            f"missing Python packages for openpi's server: {', '.join(missing)}. Install them with\n"
            "  pip install --no-deps openpi-client==0.1.2 && pip install websockets==17.4 msgpack==1.2.4"
        )
    sys.path.insert(0, str(openpi_src))
    from openpi.serving import websocket_policy_server  # noqa: PLC0415 (needs the path above)

    return websocket_policy_server


class LeRobotPolicy:
    """A LeRobot checkpoint behind openpi's ``infer(obs) -> {"actions": ...}`` interface."""

    def __init__(self, checkpoint: Path, camera_map: dict[str, str], device: str) -> None:
        import torch
        from lerobot.configs.policies import PreTrainedConfig
        from lerobot.policies import get_policy_class, make_pre_post_processors

        self._torch = torch
        if not (checkpoint / "config.json").is_file():
            raise SystemExit(
                f"{checkpoint} is not a LeRobot checkpoint folder (no config.json); give the "
                "`pretrained_model` folder, e.g. <output_dir>/checkpoints/last/pretrained_model"
            )
        config = PreTrainedConfig.from_pretrained(checkpoint)
        config.device = device
        self.config = config
        self.device = torch.device(device)
        self.policy_type = config.type

        LOG.info("loading %s policy from %s on %s", config.type, checkpoint, device)
        policy_cls = get_policy_class(config.type)
        self.policy = policy_cls.from_pretrained(checkpoint, config=config)
        self.policy.to(self.device)
        self.policy.eval()

        # The checkpoint's own processor pipelines: normalization stats exactly as trained.
        # The device steps are pointed at --device, as lerobot's async policy server does.
        device_override = {"device": device}
        self.preprocessor, self.postprocessor = make_pre_post_processors(
            config,
            pretrained_path=str(checkpoint),
            preprocessor_overrides={"device_processor": device_override},
            postprocessor_overrides={"device_processor": device_override},
        )

        env_ft = config.env_state_feature
        self.env_dim = int(env_ft.shape[0]) if env_ft is not None else None
        state_ft = config.robot_state_feature
        self.state_dim = int(state_ft.shape[0]) if state_ft is not None else None
        action_ft = config.action_feature
        self.action_dim = int(action_ft.shape[0]) if action_ft is not None else None
        if self.action_dim not in (22, 44):
            LOG.warning("the policy's action has %s values; eval expects 22 (one arm) or 44 (two arms)", self.action_dim)
        self.n_obs_steps = int(getattr(config, "n_obs_steps", 1) or 1)

        # feature -> (C, H, W) the policy was trained on
        self.image_shapes = {key: tuple(ft.shape) for key, ft in config.image_features.items()}
        self.camera_map = self._resolve_cameras(camera_map)
        LOG.info("cameras (eval key -> policy feature): %s", self.camera_map)

    def _resolve_cameras(self, camera_map: dict[str, str]) -> dict[str, str]:
        unknown = {k: f for k, f in camera_map.items() if f not in self.image_shapes}
        if unknown:
            raise SystemExit(
                f"--camera maps to features the policy does not have: {unknown}; "
                f"its image features are {sorted(self.image_shapes)}"
            )
        mapping = dict(camera_map)
        covered = set(mapping.values())
        for feature in self.image_shapes:
            if feature in covered:
                continue
            if feature.startswith(IMAGE_PREFIX) and feature[len(IMAGE_PREFIX) :] not in mapping:
                eval_key = feature[len(IMAGE_PREFIX) :]
                mapping[eval_key] = feature  # default: eval key k -> observation.images.k
                LOG.warning(
                    "no --camera for %s: expecting eval to send it as %r (eval --task sends `base` and "
                    "`wrist`; add --camera EVAL_KEY=%s otherwise)",
                    feature,
                    eval_key,
                    feature,
                )
            else:
                raise SystemExit(f"no camera for the policy's image feature {feature}: add --camera EVAL_KEY={feature}")
        return mapping

    # -- inference ---------------------------------------------------------------------

    def _build_batch(self, obs: dict[str, Any]) -> dict[str, Any]:
        from lerobot.policies import prepare_observation_for_inference

        raw: dict[str, np.ndarray] = {}
        for eval_key, feature in self.camera_map.items():
            if eval_key not in obs:
                image_keys = sorted(k for k, v in obs.items() if isinstance(v, np.ndarray) and v.ndim == 3)
                raise KeyError(
                    f"the observation has no image {eval_key!r} (needed for {feature}); it has {image_keys}. "
                    "Fix the --camera mapping."
                )
            image = np.asarray(obs[eval_key])
            if image.ndim != 3 or image.shape[-1] != 3:
                raise ValueError(f"image {eval_key!r}: expected (H, W, 3), got {image.shape}")
            if image.dtype != np.uint8:
                raise ValueError(f"image {eval_key!r}: expected uint8, got {image.dtype}")
            raw[feature] = np.array(image, copy=True)  # msgpack arrays are read-only
        if self.state_dim is not None:
            state = np.asarray(obs["state"], dtype=np.float32).reshape(-1)
            if state.shape[0] != self.state_dim:
                raise ValueError(
                    f"state has {state.shape[0]} values, the policy expects {self.state_dim} "
                    "(eval --pad-state-dim46 pads a one-arm state to 46)"
                )
            raw[STATE_KEY] = np.array(state, copy=True)
        if self.env_dim is not None:
            if "environment_state" not in obs:
                raise KeyError(
                    "the policy takes observation.environment_state, but the observation has no "
                    "environment_state: run eval with --environment-state"
                )
            env = np.asarray(obs["environment_state"], dtype=np.float32).reshape(-1)
            if env.shape[0] != self.env_dim:
                raise ValueError(f"environment_state has {env.shape[0]} values, the policy expects {self.env_dim}")
            raw[ENV_KEY] = np.array(env, copy=True)

        prompt = obs.get("prompt")
        batch = prepare_observation_for_inference(raw, self.device, task=prompt if isinstance(prompt, str) else None)

        # eval sends 224x224; bring each camera to the policy's trained resolution.
        functional = self._torch.nn.functional
        for feature, (_, height, width) in self.image_shapes.items():
            image = batch[feature]
            if tuple(image.shape[-2:]) != (height, width):
                batch[feature] = functional.interpolate(
                    image, size=(height, width), mode="bilinear", align_corners=False, antialias=True
                ).clamp_(0.0, 1.0)
        return batch

    def infer(self, obs: dict[str, Any]) -> dict[str, Any]:
        torch = self._torch
        start = time.perf_counter()
        batch = self.preprocessor(self._build_batch(obs))
        if self.n_obs_steps > 1:
            # (B, ...) -> (B, n_obs_steps, ...): the current observation repeated, as lerobot's
            # observation queues hold right after a reset.
            for key in self.config.input_features:
                if key in batch and isinstance(batch[key], torch.Tensor):
                    value = batch[key].unsqueeze(1)
                    batch[key] = value.expand(value.shape[0], self.n_obs_steps, *value.shape[2:]).contiguous()
        with torch.inference_mode():
            self.policy.reset()  # stateless: no queues carried between requests
            chunk = self.policy.predict_action_chunk(batch)
            if chunk.ndim == 2:
                chunk = chunk.unsqueeze(0)  # (B, T, action_dim)
            # lerobot's postprocessors take one (B, action_dim) action at a time
            actions = torch.stack([self.postprocessor(chunk[:, i]) for i in range(chunk.shape[1])], dim=1)
        actions_np = actions[0].detach().to("cpu", torch.float32).numpy()
        LOG.debug("answered with %s in %.1f ms", actions_np.shape, 1000 * (time.perf_counter() - start))
        return {"actions": actions_np}

    def reset(self) -> None:  # openpi's BasePolicy interface
        self.policy.reset()

    def dummy_observation(self) -> dict[str, Any]:
        obs: dict[str, Any] = {
            key: np.zeros((EVAL_IMAGE_SIZE, EVAL_IMAGE_SIZE, 3), dtype=np.uint8) for key in self.camera_map
        }
        if self.state_dim is not None:
            obs["state"] = np.zeros(self.state_dim, dtype=np.float64)
        if self.env_dim is not None:
            obs["environment_state"] = np.zeros(self.env_dim, dtype=np.float64)
        obs["prompt"] = ""
        return obs


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="Serve a LeRobot checkpoint to `dexjoco-data eval` through openpi's websocket policy server.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=__doc__.split("Usage:", 1)[1] if "Usage:" in __doc__ else None,
    )
    parser.add_argument("--checkpoint", required=True, type=Path, help="LeRobot pretrained_model folder")
    parser.add_argument("--host", default="0.0.0.0", help="address to listen on (default: 0.0.0.0)")
    parser.add_argument("--port", type=int, default=8000, help="port to listen on (default: 8000)")
    parser.add_argument(
        "--camera",
        action="append",
        default=[],
        metavar="EVAL_KEY=FEATURE",
        help="map an image key eval sends (base, wrist, ...) to the policy's image feature "
        "(observation.images.<camera>); repeatable",
    )
    parser.add_argument(
        "--openpi-src",
        type=Path,
        default=DEFAULT_OPENPI_SRC,
        help=f"openpi's src folder (default: {DEFAULT_OPENPI_SRC})",
    )
    parser.add_argument("--device", default="cpu", help="torch device: cpu, cuda, cuda:1, mps (default: cpu)")
    parser.add_argument("-v", "--verbose", action="store_true", help="log every request")
    args = parser.parse_args(argv)

    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
        force=True,
    )
    server_module = import_openpi_server(args.openpi_src.resolve())
    checkpoint = args.checkpoint.resolve()
    policy = LeRobotPolicy(checkpoint, parse_camera_map(args.camera), args.device)

    start = time.perf_counter()
    warmup = policy.infer(policy.dummy_observation())
    chunk_len, action_dim = warmup["actions"].shape
    LOG.info("warm-up inference: actions %s in %.2f s", warmup["actions"].shape, time.perf_counter() - start)
    if chunk_len < 30:
        LOG.warning("the policy returns %d actions per chunk; eval buffers 30 and asks again below 24", chunk_len)

    metadata = {
        "policy_type": policy.policy_type,
        "checkpoint": str(checkpoint),
        "chunk_size": int(chunk_len),
        "action_dim": int(action_dim),
        "n_obs_steps": policy.n_obs_steps,
        "cameras": dict(policy.camera_map),
        "server": "examples/serve_lerobot_policy.py",
    }
    server = server_module.WebsocketPolicyServer(policy=policy, host=args.host, port=args.port, metadata=metadata)
    LOG.info("serving %s on ws://%s:%d (metadata %s)", policy.policy_type, args.host, args.port, metadata)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        LOG.info("stopped")
    return 0


if __name__ == "__main__":
    sys.exit(main())
