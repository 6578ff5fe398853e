#!/usr/bin/env bash
# Episodes per minute of `dexjoco-data eval` (-j 1 and -j 2) and of the DexJoCo reference
# client (eval_dexjoco_openpi.py as shipped, and with its environments' 30 Hz sleep
# removed), side by side on this machine, against the same policy server (openpi's
# WebsocketPolicyServer with a policy that holds the pose, so every episode runs to the
# step cap on both sides: the same work per episode). Both render the reference scene's
# cameras at 640x640 with the reference's quality and record the config's videos. The
# step cap (default 200 of hammer_nail's 1000: `eval --step-cap`, and the same cap
# patched into the reference client's environment) keeps a CPU run to minutes; the table
# gives steps per second and the episodes per minute of full 1000-step episodes they make.
#
#   scripts/bench-eval.sh [EPISODES_OURS] [EPISODES_REFERENCE] [STEP_CAP]   # default 4, 2, 200
#
# Needs a release build (cargo build --release) and the venvs of scripts/setup.sh --python.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
OURS_N="${1:-4}"
REF_N="${2:-2}"
CAP="${3:-200}"
B="${DEXJOCO_BIN:-$ROOT/target/release/dexjoco-data}"
R="$(cat "$ROOT/.deps/reference-python-path")"
UP="${DEXJOCO_UPSTREAM:-$ROOT/../shared/dexjoco-upstream}"
export DEXJOCO_REFERENCE_CODE="${DEXJOCO_REFERENCE_CODE:-$ROOT/../shared/third_party/dexjoco-8d23b0f}"
export DEXJOCO_UPSTREAM="$UP"
CONFIG="$UP/task-configs/rand_obj/hammer_nail.yaml"
TMP="$(mktemp -d)"
trap 'kill $SERVER 2>/dev/null || true; rm -rf "$TMP"' EXIT
PORT="$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')"
"$R" tests/python/policy_server.py --port "$PORT" hold > "$TMP/server.log" 2>&1 &
SERVER=$!
until grep -q listening "$TMP/server.log"; do sleep 0.2; done

# | client | episodes | steps | seconds | steps / s | 1000-step episodes / min |
row() {
  python3 -c "import sys; c, n, k, s = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]); print(f'| {c} | {n} | {k} | {s:.0f} | {k / s:.1f} | {k / s * 60 / 1000:.2f} |')" "$@"
}
# Steps our episodes ran (warm-up included, as the reference's env_step counts them).
our_steps() {
  python3 -c "import json, pathlib, sys; rs = [json.loads(p.read_text()) for p in pathlib.Path(sys.argv[1]).glob('episode_*/episode.json')]; print(sum(r['steps'] + r['warmup_steps'] for r in rs))" "$1"
}

echo "| client | episodes | steps | seconds | steps / s | 1000-step episodes / min |"
echo "|---|---:|---:|---:|---:|---:|"
for j in 1 2; do
  start=$(date +%s.%N)
  "$B" -q -j "$j" eval --config "$CONFIG" --scene-dir "$UP/xmls" --episodes "$OURS_N" \
    --step-cap "$CAP" --host 127.0.0.1 --port "$PORT" --output "$TMP/ours-j$j" >/dev/null
  end=$(date +%s.%N)
  row "dexjoco-data eval -j $j" "$OURS_N" "$(our_steps "$TMP/ours-j$j")" "$(python3 -c "print($end - $start)")"
done
for mode in shipped no-sleep; do
  flag=""; [ "$mode" = no-sleep ] && flag="--no-sleep"
  out="$("$R" tests/python/reference_eval_client.py --config "$CONFIG" --port "$PORT" \
    --episodes "$REF_N" --step-cap "$CAP" --out "$TMP/ref-$mode" $flag 2>/dev/null | tail -1)"
  field() { python3 -c "import json,sys; print(json.loads(sys.argv[1])[sys.argv[2]])" "$out" "$1"; }
  row "reference client ($mode)" "$REF_N" "$(field steps)" "$(field seconds)"
done
