#!/usr/bin/env bash
# Does generation help a policy? For each task, from the same source demonstrations:
#   (a) augment only:      the sources, each replayed A times under visual randomization;
#   (b) generate + augment: G new demonstrations at new object poses made from the same
#                           sources, each replayed B times;
# about the same number of frames in both (A and B are chosen so), converted to LeRobot
# v3.0, the same small ACT policy trained with lerobot-train for STEPS steps on the CPU,
# served by examples/serve_lerobot_policy.py and evaluated by `dexjoco-data eval
# --rand-full` (object poses drawn anew every episode, the paper's rand-full look) on the
# same EPISODES resets of seed 0. Prints the success rates side by side (reported, not
# asserted) and writes them to OUT/results.md.
#
#   scripts/bench-generate-policy.sh [OUT]
#
# Environment: TASKS (default "click_mouse hammer_nail"), STEPS (ACT training steps,
# default 1000), EPISODES (eval episodes, default 20), GENERATED (G, default 10),
# SIZE (image side, default 96), BIN (default target/release/dexjoco-data). Needs the
# test venv (scripts/setup.sh --python) and the reference code beside the checkout
# (openpi's websocket server). Sources: the task's sample demonstrations (datasets/demos).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="$(mkdir -p "${1:-$ROOT/bench-generate-policy}" && cd "${1:-$ROOT/bench-generate-policy}" && pwd)"
TASKS="${TASKS:-click_mouse hammer_nail}"
STEPS="${STEPS:-1000}"
EPISODES="${EPISODES:-20}"
GENERATED="${GENERATED:-10}"
SIZE="${SIZE:-96}"
BIN="${BIN:-$ROOT/target/release/dexjoco-data}"
PY="$(cat "$ROOT/.deps/python-path")"
VENV_BIN="$(dirname "$PY")"
OPENPI_SRC="$ROOT/../shared/third_party/dexjoco-8d23b0f/openpi/src"
log() { printf '[bench-generate-policy] %s\n' "$*" >&2; }
[ -x "$BIN" ] || { log "no $BIN: cargo build --release"; exit 1; }
[ -x "$VENV_BIN/lerobot-train" ] || { log "no lerobot-train in the test venv: scripts/setup.sh --python"; exit 1; }
[ -d "$OPENPI_SRC" ] || { log "no openpi source at $OPENPI_SRC"; exit 1; }

# Frames of the raw episodes under $1 (their action arrays' rows).
frames() {
  "$PY" - "$1" <<'EOF'
import sys, pathlib, zarr
n = 0
for z in pathlib.Path(sys.argv[1]).rglob("replay.zarr"):
    if any(p.startswith(".") for p in z.relative_to(sys.argv[1]).parts):
        continue
    n += zarr.open(str(z), mode="r")["data"]["action"].shape[0]
print(n)
EOF
}

# Trains ACT on dataset $1 into $2, serves it on a free port, evaluates EPISODES
# episodes of task $3 into $4; prints "successes episodes".
train_and_eval() {
  local dataset=$1 train=$2 task=$3 eval=$4
  if [ ! -f "$train/checkpoints/last/pretrained_model/model.safetensors" ]; then
    rm -rf "$train"
    HF_HUB_OFFLINE=1 WANDB_MODE=disabled "$VENV_BIN/lerobot-train" \
      --dataset.repo_id="local/$task" --dataset.root="$dataset" --policy.type=act \
      --policy.device=cpu --policy.push_to_hub=false \
      --policy.pretrained_backbone_weights=null --policy.chunk_size=30 \
      --policy.n_action_steps=30 --batch_size=8 --steps="$STEPS" --save_freq="$STEPS" \
      --num_workers=0 --wandb.enable=false --output_dir="$train" >"$train.log" 2>&1
  fi
  local port
  port="$("$PY" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')"
  "$PY" "$ROOT/examples/serve_lerobot_policy.py" \
    --checkpoint "$train/checkpoints/last/pretrained_model" \
    --camera base=observation.images.third_person --camera wrist=observation.images.handcam_rgb \
    --host 127.0.0.1 --port "$port" --openpi-src "$OPENPI_SRC" >"$train.serve.log" 2>&1 &
  local server=$!
  "$BIN" -q eval --task "$task" --episodes "$EPISODES" --rand-full --host 127.0.0.1 \
    --port "$port" --render-size "${SIZE}x${SIZE}" --quality fast --no-videos -j 1 \
    --server-wait 300 --seed 0 --output "$eval" >/dev/null || true
  kill "$server" 2>/dev/null || true
  wait "$server" 2>/dev/null || true
  local ok
  ok="$(find "$eval" -maxdepth 1 -name 'episode_*_success' | wc -l)"
  echo "$ok $(find "$eval" -maxdepth 1 -name 'episode_*_*' -type d | wc -l)"
}

echo "| task | sources | data | episodes | frames | successes (rand-full, seed 0) |" >"$OUT/results.md"
echo "|---|---:|---|---:|---:|---:|" >>"$OUT/results.md"
for task in $TASKS; do
  work="$OUT/$task"
  mkdir -p "$work"
  sources="$ROOT/datasets/demos/$task"
  n_src="$(find "$sources" -maxdepth 1 -name 'episode_*' | wc -l)"
  src_frames="$(frames "$sources")"
  # (b) first: its frames decide (a)'s replays.
  log "$task: generate $GENERATED from $n_src source(s)"
  "$BIN" -q --work-dir "$work/b" generate "$sources" --task "$task" --count "$GENERATED" >/dev/null
  gen_frames="$(frames "$work/b/generate/$task")"
  b_replays=2
  a_replays=$(( (gen_frames * b_replays + src_frames / 2) / src_frames ))
  ((a_replays >= 1)) || a_replays=1
  log "$task: (a) $n_src source(s) x $a_replays replays; (b) $GENERATED generated x $b_replays replays"
  "$BIN" -q --work-dir "$work/a" augment "$sources" --replays "$a_replays" --size "$SIZE" \
    --quality fast --camera handcam_rgb >/dev/null
  "$BIN" -q --work-dir "$work/b" augment "$work/b/generate/$task" --replays "$b_replays" \
    --size "$SIZE" --quality fast --camera handcam_rgb >/dev/null
  for side in a b; do
    "$BIN" -q --work-dir "$work/$side" convert --overwrite >/dev/null
    result="$(train_and_eval "$work/$side/convert/lerobot-v3" "$work/$side/train_act" "$task" "$work/$side/eval")"
    ok="${result% *}" total="${result#* }"
    episodes="$(find "$work/$side/augment/$task" -mindepth 1 -maxdepth 1 -type d | wc -l)"
    label="augment only"
    [ "$side" = b ] && label="generate ($GENERATED) + augment"
    echo "| $task | $n_src | $label | $episodes | $(frames "$work/$side/augment") | $ok/$total |" >>"$OUT/results.md"
    log "$task ($label): $ok/$total"
  done
done
cat "$OUT/results.md"
