#!/usr/bin/env bash
# The measurement a GPU node is asked for (issue #48): the Warp batch renderer on CUDA.
# Prepared on a CPU-only machine, where the same steps run on Warp's CPU device
# (`--device cpu`); on a node with an NVIDIA GPU and PyPI reachable, run it as is.
#
#   1. the Warp renderer's venv (scripts/setup.sh --warp: mujoco, mujoco-warp, warp-lang
#      as scripts/warp-requirements.txt pins them), and `doctor`'s Warp line;
#   2. `bench fidelity` on hammer_nail (Warp vs OpenGL, PSNR/SSIM, pictures);
#   3. `bench augment --renderer warp` on the hammer_nail sample at 224 px, for each
#      batch size given (frames/s, and where a frame's time goes: scene update = poses
#      packed and piped to the worker and uploaded; render = BVH refit + ray tracing;
#      readback; x264 on the node's CPU cores), one run per worker count;
#   4. the OpenGL renderer's `bench augment` on the same episodes, side by side.
# Everything under <out> (default dexjoco-work/bench-warp-gpu): the logs and JSON.
#
# Usage: scripts/bench-warp-gpu.sh [--bin PATH] [--device cuda:0|cpu] [--batches "512 2048 8192"]
#                                  [--workers "1,4,8"] [--replays N] [--out DIR]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bin="target/release/dexjoco-data" device="cuda:0" batches="512 2048 8192" workers="1,4,8"
replays=16 out="dexjoco-work/bench-warp-gpu"
while (($#)); do
  case "$1" in
    --bin) bin="$2"; shift 2 ;;
    --device) device="$2"; shift 2 ;;
    --batches) batches="$2"; shift 2 ;;
    --workers) workers="$2"; shift 2 ;;
    --replays) replays="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
    *) echo "bench-warp-gpu.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
mkdir -p "$out"
log() { printf '\033[1m[bench-warp-gpu]\033[0m %s\n' "$*" >&2; }

./scripts/setup.sh --warp >&2
export DEXJOCO_WARP_PYTHON="$(cat .deps/warp-python-path)"
{ command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv; } \
  > "$out/gpu.txt" 2>&1 || true
"$bin" doctor > "$out/doctor.txt" 2>&1 || true
tail -3 "$out/doctor.txt" >&2

log "fidelity (hammer_nail, 224 px, 4 views)"
"$bin" --work-dir "$out/work" -q bench fidelity --task hammer_nail --views 4 \
  --warp-device "$device" | tee "$out/fidelity.txt"

common=(datasets/demos/hammer_nail --replays "$replays" --size 224 --quality fast
        --max-frames 0 --no-reference --limit-frames 0 --workers "$workers")
for b in $batches; do
  log "bench augment --renderer warp, batch $b, workers $workers"
  "$bin" --work-dir "$out/work-$b" -q bench augment "${common[@]}" \
    --renderer warp --warp-device "$device" --warp-batch "$b" | tee "$out/augment-warp-$b.txt"
done
log "bench augment, OpenGL renderer, same episodes"
"$bin" --work-dir "$out/work-gl" -q bench augment "${common[@]}" | tee "$out/augment-opengl.txt"
log "done: $out"
