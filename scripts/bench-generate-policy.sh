#!/usr/bin/env bash
# Does generation help a policy that sees? The camera-image twin of scripts/bench-policy.sh.
# For each task, from ONE source demonstration on the DexJoCo reference scenes (a `scripted`
# plan, the first seed from SOURCE_SEED that succeeds):
#   (a) source alone: the source replayed by `augment` under visual randomization (camera,
#       lights, table texture) as many times as gives about the frames of the largest
#       generated set (at most REPLAYS);
#   (b) source + N generated: N demonstrations made by `generate` (seed GEN_SEED) at new
#       object poses, each replayed once by `augment` with the source, for each N in NS
#       (the first N of one run: they nest);
# converted to LeRobot v3.0 (two cameras: the randomized third_person and handcam_rgb, SIZE px), the same
# ACT policy with its image backbone trained on each with lerobot-train (chunk 30, batch
# BATCH, STEPS steps; BACKBONE=ResNet18_Weights.IMAGENET1K_V1 for ImageNet weights where
# the Hub is reachable, random-init by default), served by examples/serve_lerobot_policy.py
# and evaluated by `dexjoco-data eval --rand-full` (object poses, camera, lights and table
# drawn anew every episode) on the same EPISODES resets of EVAL_SEED on the same scenes.
# Reported, not asserted: OUT/results.md and OUT/results.json. Everything already made in
# OUT is reused: rerun to resume.
#
#   scripts/bench-generate-policy.sh [OUT]
#   # a smoke run on a CPU (minutes; no policy converges):
#   TASKS=click_mouse NS=4 STEPS=20 EPISODES=2 REPLAYS=5 SIZE=64 scripts/bench-generate-policy.sh OUT
#
# Environment: TASKS (default "click_mouse hammer_nail pick_bucket"), NS ("10 100 1000"),
# EPISODES (50), STEPS (100000; a GPU node's job), BATCH (8), SIZE (96), REPLAYS (1000),
# SOURCE_SEED (1), GEN_SEED (11), EVAL_SEED (0), SCENES (../shared/dexjoco-upstream/xmls;
# "builtin" for the built-in scenes), BACKBONE (null), DEVICE (cpu; cuda on a GPU node),
# BIN (target/release/dexjoco-data). Needs the test venv (scripts/setup.sh --python) and
# the reference code beside the checkout (openpi's websocket server).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="$(mkdir -p "${1:-$ROOT/bench-generate-policy}" && cd "${1:-$ROOT/bench-generate-policy}" && pwd)"
TASKS="${TASKS:-click_mouse hammer_nail pick_bucket}"
NS="${NS:-10 100 1000}"
EPISODES="${EPISODES:-50}"
STEPS="${STEPS:-100000}"
BATCH="${BATCH:-8}"
SIZE="${SIZE:-96}"
REPLAYS="${REPLAYS:-1000}"
SOURCE_SEED="${SOURCE_SEED:-1}"
GEN_SEED="${GEN_SEED:-11}"
EVAL_SEED="${EVAL_SEED:-0}"
SCENES="${SCENES:-$ROOT/../shared/dexjoco-upstream/xmls}"
BACKBONE="${BACKBONE:-null}"
DEVICE="${DEVICE:-cpu}"
BIN="${BIN:-$ROOT/target/release/dexjoco-data}"
PY="$(cat "$ROOT/.deps/python-path")"
VENV_BIN="$(dirname "$PY")"
OPENPI_SRC="$ROOT/../shared/third_party/dexjoco-8d23b0f/openpi/src"
log() { printf '[bench-generate-policy] %s\n' "$*" >&2; }
[ -x "$BIN" ] || { log "no $BIN: cargo build --release"; exit 1; }
[ -x "$VENV_BIN/lerobot-train" ] || { log "no lerobot-train in the test venv: scripts/setup.sh --python"; exit 1; }
[ -d "$OPENPI_SRC" ] || { log "no openpi source at $OPENPI_SRC"; exit 1; }
SCENE_ARGS=()
[ "$SCENES" = builtin ] || SCENE_ARGS=(--scene-dir "$SCENES")
RENDER=(--size "$SIZE" --quality fast --camera handcam_rgb)  # + the randomized third_person
MAX_N=0
for n in $NS; do [ "$n" -gt "$MAX_N" ] && MAX_N=$n; done

. "$ROOT/scripts/bench-common.sh"

# Trains ACT on dataset $2 into $1/act_$3 (kept if there), serves it, evaluates task $4
# with --rand-full into $1/ev_$3; appends a line to results.json.
train_and_eval() {
  local dir=$1 dataset=$2 name=$3 task=$4 arm=$5 n=$6
  local train="$dir/act_$name" ev="$dir/ev_$name"
  if [ ! -f "$train/checkpoints/last/pretrained_model/model.safetensors" ]; then
    rm -rf "$train"
    log "$task $name: training ACT ($STEPS steps, batch $BATCH, $DEVICE)"
    HF_HUB_OFFLINE=1 WANDB_MODE=disabled "$VENV_BIN/lerobot-train" \
      --dataset.repo_id="local/$task" --dataset.root="$dataset" --policy.type=act \
      --policy.device="$DEVICE" --policy.push_to_hub=false \
      --policy.pretrained_backbone_weights="$BACKBONE" --policy.chunk_size=30 \
      --policy.n_action_steps=30 --batch_size="$BATCH" --steps="$STEPS" --save_freq="$STEPS" \
      --log_freq=100 --num_workers=0 --wandb.enable=false --output_dir="$train" >"$train.log" 2>&1
  fi
  if [ ! -f "$ev/.done" ]; then
    local port
    port="$(free_port)"
    "$PY" "$ROOT/examples/serve_lerobot_policy.py" \
      --checkpoint "$train/checkpoints/last/pretrained_model" \
      --camera base=observation.images.third_person --camera wrist=observation.images.handcam_rgb \
      --host 127.0.0.1 --port "$port" --openpi-src "$OPENPI_SRC" >"$train.serve.log" 2>&1 &
    local server=$!
    rm -rf "$ev"
    log "$task $name: evaluating $EPISODES episodes (--rand-full)"
    "$BIN" -q eval --task "$task" --episodes "$EPISODES" --rand-full --seed "$EVAL_SEED" \
      "${SCENE_ARGS[@]}" --host 127.0.0.1 --port "$port" --render-size "${SIZE}x${SIZE}" \
      --quality fast --no-videos -j 1 --server-wait 300 --output "$ev" >"$ev.log" 2>&1 || true
    kill "$server" 2>/dev/null || true
    wait "$server" 2>/dev/null || true
    touch "$ev/.done"
  fi
  "$PY" - "$ev" "$task" "$arm" "$n" "$dataset" >>"$OUT/results.json" <<'EOF'
import json, sys, pathlib
ev, task, arm, n, dataset = sys.argv[1:6]
records = [json.loads(p.read_text()) for p in pathlib.Path(ev).glob("episode_*/episode.json")]
info = json.loads((pathlib.Path(dataset) / "meta/info.json").read_text())
print(json.dumps({
    "task": task, "arm": arm, "generated": int(n), "episodes_in_data": info["total_episodes"],
    "frames": info["total_frames"], "evaluated": len(records),
    "successes": sum(r["success"] for r in records),
    "subtasks_done": sum(sum(s["end"] is not None for s in r["subtasks"]) for r in records),
}))
EOF
}

: >"$OUT/results.json"
for task in $TASKS; do
  dir="$OUT/$task"
  mkdir -p "$dir"
  scripted_source "$task" "$dir"
  src="$dir/source/$task"
  log "$task: generating $MAX_N demonstrations"
  "$BIN" -q generate "$src" --task "$task" --count "$MAX_N" --seed "$GEN_SEED" "${SCENE_ARGS[@]}" \
    --out "$dir/generated" >"$dir/generate.log" 2>&1
  # (b): the source and every generated episode replayed once, the source first; each N
  # is the first N + 1 episodes.
  if [ ! -f "$dir/ds_all/meta/info.json" ]; then
    log "$task: rendering the source and $MAX_N generated demonstrations"
    "$BIN" -q augment "$src" --replays 1 "${RENDER[@]}" "${SCENE_ARGS[@]}" --out "$dir/aug_source1" \
      >"$dir/augment_source1.log" 2>&1
    "$BIN" -q augment "$dir/generated/$task" --replays 1 "${RENDER[@]}" "${SCENE_ARGS[@]}" \
      --out "$dir/aug_generated" >"$dir/augment_generated.log" 2>&1 || true
    "$BIN" -q convert "$dir/aug_source1" "$dir/aug_generated" --out "$dir/ds_all" --overwrite \
      >"$dir/convert_all.log" 2>&1
  fi
  # (a): the source alone, replayed to about as many frames as the largest set.
  per=$(frames "$src")
  replays=$(( ($(frames "$dir/generated/$task") + per - 1) / per ))
  [ "$replays" -gt "$REPLAYS" ] && replays=$REPLAYS
  [ "$replays" -ge 1 ] || replays=1
  if [ ! -f "$dir/ds_source/meta/info.json" ]; then
    log "$task: the source replayed $replays times"
    "$BIN" -q augment "$src" --replays "$replays" "${RENDER[@]}" "${SCENE_ARGS[@]}" \
      --out "$dir/aug_source" >"$dir/augment_source.log" 2>&1 || true
    "$BIN" -q convert "$dir/aug_source" --out "$dir/ds_source" --overwrite >"$dir/convert_source.log" 2>&1
  fi
  train_and_eval "$dir" "$dir/ds_source" source "$task" source 0
  for n in $NS; do
    if [ ! -f "$dir/ds_$n/meta/info.json" ]; then
      "$BIN" -q dataset filter "$dir/ds_all" --episodes "0-$n" --out "$dir/ds_$n" --overwrite >/dev/null
    fi
    train_and_eval "$dir" "$dir/ds_$n" "gen$n" "$task" generated "$n"
  done
done

"$PY" - "$OUT" <<'EOF'
import json, sys, pathlib
out = pathlib.Path(sys.argv[1])
rows = [json.loads(l) for l in (out / "results.json").read_text().splitlines() if l.strip()]
md = ["| task | data | episodes | frames | success, rand-full (of evaluated) | subtasks done |",
      "|---|---|---:|---:|---:|---:|"]
for r in rows:
    data = "source alone (replays)" if r["arm"] == "source" else f"source + {r['generated']} generated"
    rate = 100.0 * r["successes"] / max(1, r["evaluated"])
    md.append(f"| {r['task']} | {data} | {r['episodes_in_data']} | {r['frames']} | "
              f"{rate:.0f} % ({r['successes']}/{r['evaluated']}) | {r['subtasks_done']} |")
(out / "results.md").write_text("\n".join(md) + "\n")
print("\n".join(md))
EOF
log "results: $OUT/results.md"
