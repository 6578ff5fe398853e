#!/usr/bin/env bash
# Episodes per minute of `dexjoco-data eval` (-j 1 and -j 2) and of the DexJoCo reference
# client (eval_dexjoco_openpi.py as shipped, and with its environments' 30 Hz sleep
# removed), side by side on this machine, against the same policy server (openpi's
# WebsocketPolicyServer with a policy that holds the pose, so every episode runs to the
# task's step cap on both sides: the same work per episode). Both render the reference
# scene's cameras at 640x640 and record the config's videos.
#
#   scripts/bench-eval.sh [EPISODES_OURS] [EPISODES_REFERENCE]   # default 4 and 2
#
# Needs a release build (cargo build --release) and the venvs of scripts/setup.sh --python.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
OURS_N="${1:-4}"
REF_N="${2:-2}"
B="${DEXJOCO_BIN:-$ROOT/target/release/dexjoco-data}"
R="$(cat "$ROOT/.deps/reference-python-path")"
UP="${DEXJOCO_UPSTREAM:-$ROOT/../shared/dexjoco-upstream}"
export DEXJOCO_REFERENCE_CODE="${DEXJOCO_REFERENCE_CODE:-$ROOT/../shared/third_party/dexjoco-8d23b0f}"
export DEXJOCO_UPSTREAM="$UP"
CONFIG="$UP/task-configs/rand_obj/hammer_nail.yaml"
TMP="$(mktemp -d)"
trap 'kill $SERVER 2>/dev/null || true; rm -rf "$TMP"' EXIT
PORT="$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')"
mkdir -p "$TMP/no-plans"
"$R" tests/python/policy_server.py --port "$PORT" oracle --plans "$TMP/no-plans" > "$TMP/server.log" 2>&1 &
SERVER=$!
until grep -q listening "$TMP/server.log"; do sleep 0.2; done

rate() { python3 -c "import sys; n, s = float(sys.argv[1]), float(sys.argv[2]); print(f'{n / s * 60:.2f}')" "$1" "$2"; }
row() { printf '| %s | %s | %.0f | %s |\n' "$1" "$2" "$3" "$(rate "$2" "$3")"; }

echo "| client | episodes | seconds | episodes / min |"
echo "|---|---:|---:|---:|"
for j in 1 2; do
  start=$(date +%s.%N)
  "$B" -q -j "$j" eval --config "$CONFIG" --scene-dir "$UP/xmls" --episodes "$OURS_N" \
    --host 127.0.0.1 --port "$PORT" --output "$TMP/ours-j$j" >/dev/null
  end=$(date +%s.%N)
  row "dexjoco-data eval -j $j" "$OURS_N" "$(python3 -c "print($end - $start)")"
done
for mode in shipped no-sleep; do
  flag=""; [ "$mode" = no-sleep ] && flag="--no-sleep"
  out="$("$R" tests/python/reference_eval_client.py --config "$CONFIG" --port "$PORT" \
    --episodes "$REF_N" --out "$TMP/ref-$mode" $flag 2>/dev/null | tail -1)"
  secs="$(python3 -c "import json,sys; print(json.loads(sys.argv[1])['seconds'])" "$out")"
  row "reference client ($mode)" "$REF_N" "$secs"
done
