#!/usr/bin/env bash
# Does generation make a better policy? For each task, from ONE source demonstration on the
# DexJoCo reference scenes (a `scripted` plan, seed SOURCE_SEED):
#   (a) source alone: the source replayed REPLAYS times under dynamics randomization
#       (augment --dynamics), as many frames as the largest generated set (capped);
#   (b) source + N generated demonstrations (generate, seed GEN_SEED), for each N in NS
#       (the first N of one run: they nest);
# each converted to LeRobot v3.0 with the per-frame environment state
# (convert --environment-state), the same state-based policy trained on each on the CPU
# (examples/bc_policy.py: robomimic's low-dimensional BC, an MLP of two 1,024 layers,
# batch 100, STEPS steps; rotations as 6D), served through openpi's websocket protocol and
# evaluated by `dexjoco-data eval --environment-state --no-cameras` on the same EPISODES
# rand_obj resets (seed EVAL_SEED; object poses drawn anew every episode) on the same
# scenes. Reported, not asserted: OUT/results.md (table), OUT/results.json (one line per
# run; every task in OUT, so runs for different TASKS may share it, one after the other or
# side by side), OUT/results.svg (success and subtasks ended against N per task), OUT/<task>/pol_*/curve.csv (training
# curves). Everything already made in OUT is reused: rerun to resume.
#
#   scripts/bench-policy.sh [OUT]
#
# Environment: TASKS (default "click_mouse hammer_nail pick_bucket bimanual_unlock_ipad"),
# NS (default "10 100 1000"), EPISODES (50), STEPS (20000), THREADS (2, torch's threads
# for training: 1 where two runs share 2 cores, else they spin against each other), REPLAYS (1000, most source
# replays for arm (a)), SOURCE_SEED (1), GEN_SEED (11), EVAL_SEED (0), SCENES (default
# ../shared/dexjoco-upstream/xmls; "builtin" for the built-in scenes), BIN (default
# target/release/dexjoco-data). Needs the test venv (scripts/setup.sh --python: torch,
# pyarrow, openpi-client) and openpi's source beside the checkout (the reference code).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="$(mkdir -p "${1:-$ROOT/bench-policy}" && cd "${1:-$ROOT/bench-policy}" && pwd)"
TASKS="${TASKS:-click_mouse hammer_nail pick_bucket bimanual_unlock_ipad}"
NS="${NS:-10 100 1000}"
EPISODES="${EPISODES:-50}"
STEPS="${STEPS:-20000}"
THREADS="${THREADS:-2}"
REPLAYS="${REPLAYS:-1000}"
SOURCE_SEED="${SOURCE_SEED:-1}"
GEN_SEED="${GEN_SEED:-11}"
EVAL_SEED="${EVAL_SEED:-0}"
SCENES="${SCENES:-$ROOT/../shared/dexjoco-upstream/xmls}"
BIN="${BIN:-$ROOT/target/release/dexjoco-data}"
PY="$(cat "$ROOT/.deps/python-path")"
BC="$ROOT/examples/bc_policy.py"
log() { printf '[bench-policy] %s\n' "$*" >&2; }
[ -x "$BIN" ] || { log "no $BIN: cargo build --release"; exit 1; }
SCENE_ARGS=()
[ "$SCENES" = builtin ] || SCENE_ARGS=(--scene-dir "$SCENES")
MAX_N=0
for n in $NS; do [ "$n" -gt "$MAX_N" ] && MAX_N=$n; done

. "$ROOT/scripts/bench-common.sh"

# Trains the policy on dataset $2 into $1/pol_$3 (kept if there), serves it, evaluates
# task $4 into $1/ev_$3; writes its line of results to $1/result_$3.json.
train_and_eval() {
  local dir=$1 dataset=$2 name=$3 task=$4 arm=$5 n=$6
  local pol="$dir/pol_$name" ev="$dir/ev_$name"
  if [ ! -f "$pol/model.pt" ]; then
    log "$task $name: training ($STEPS steps)"
    "$PY" "$BC" train "$dataset" "$pol" --steps "$STEPS" --threads "$THREADS" --log-every 1000 \
      >"$pol.train.log" 2>&1
  fi
  if [ ! -f "$ev/.done" ]; then
    local port
    port="$(free_port)"
    "$PY" "$BC" serve "$pol/model.pt" --port "$port" >"$pol.serve.log" 2>&1 &
    local server=$!
    rm -rf "$ev"
    log "$task $name: evaluating $EPISODES episodes"
    "$BIN" -q eval --task "$task" --episodes "$EPISODES" --seed "$EVAL_SEED" "${SCENE_ARGS[@]}" \
      --environment-state --no-cameras --no-videos --host 127.0.0.1 --port "$port" \
      --server-wait 120 -j 1 --output "$ev" >"$ev.log" 2>&1 || true
    kill "$server" 2>/dev/null || true
    wait "$server" 2>/dev/null || true
    touch "$ev/.done"
  fi
  "$PY" - "$dir" "$name" "$task" "$arm" "$n" "$dataset" >"$dir/result_$name.json" <<'EOF'
import json, sys, pathlib
d, name, task, arm, n, dataset = sys.argv[1:7]
ev = pathlib.Path(d) / f"ev_{name}"
records = [json.loads(p.read_text()) for p in ev.glob("episode_*/episode.json")]
info = json.loads((pathlib.Path(dataset) / "meta/info.json").read_text())
curve = (pathlib.Path(d) / f"pol_{name}/curve.csv").read_text().split("\n")
last = curve[-2].split(",") if len(curve) > 1 else ["", "nan", "nan", "nan"]
print(json.dumps({
    "task": task, "arm": arm, "generated": int(n), "episodes_in_data": info["total_episodes"],
    "frames": info["total_frames"], "evaluated": len(records),
    "successes": sum(r["success"] for r in records),
    "subtasks_done": sum(sum(s["end"] is not None for s in r["subtasks"]) for r in records),
    "frames_rendered": sum(r.get("frames_rendered", 0) for r in records),
    "train_seconds": float(last[3]), "loss": float(last[1]), "held_out_loss": float(last[2]),
}))
EOF
}

for task in $TASKS; do
  dir="$OUT/$task"
  mkdir -p "$dir"
  # One source demonstration: the first seed from SOURCE_SEED whose plan succeeds.
  scripted_source "$task" "$dir"
  src="$dir/source/$task"
  # (b) the generated demonstrations, MAX_N of them (resumes where it stopped).
  log "$task: generating $MAX_N demonstrations"
  "$BIN" -q generate "$src" --task "$task" --count "$MAX_N" --seed "$GEN_SEED" "${SCENE_ARGS[@]}" \
    --out "$dir/generated" >"$dir/generate.log" 2>&1
  if [ ! -f "$dir/ds_all/meta/info.json" ]; then
    "$BIN" -q convert "$src" "$dir/generated/$task" --environment-state --no-skip-static \
      --out "$dir/ds_all" --overwrite >"$dir/convert_all.log" 2>&1
  fi
  # (a) the source alone, replayed under dynamics randomization to about as many frames.
  per=$(frames "$src")
  gen_frames=$(frames "$dir/generated/$task")
  replays=$(( (gen_frames + per - 1) / per ))
  [ "$replays" -gt "$REPLAYS" ] && replays=$REPLAYS
  if [ ! -f "$dir/ds_source/meta/info.json" ]; then
    log "$task: the source replayed $replays times under dynamics randomization"
    "$BIN" -q augment "$src" --replays "$replays" --dynamics --size 32 --quality fast \
      "${SCENE_ARGS[@]}" --out "$dir/augmented" >"$dir/augment.log" 2>&1 || true
    "$BIN" -q convert "$dir/augmented" --environment-state --no-skip-static --out "$dir/ds_source" \
      --overwrite >"$dir/convert_source.log" 2>&1
  fi
  train_and_eval "$dir" "$dir/ds_source" source "$task" source 0
  for n in $NS; do
    if [ ! -f "$dir/ds_$n/meta/info.json" ]; then
      "$BIN" -q dataset filter "$dir/ds_all" --episodes "0-$n" --out "$dir/ds_$n" --overwrite >/dev/null
    fi
    train_and_eval "$dir" "$dir/ds_$n" "gen$n" "$task" generated "$n"
  done
done

# The report covers every task in OUT (runs for other TASKS into the same OUT included).
"$PY" - "$OUT" <<'EOF'
import json, sys, pathlib
out = pathlib.Path(sys.argv[1])
rows = []
for p in sorted(out.glob("*/result_*.json")):
    r = json.loads(p.read_text())
    # The subtasks there were to end: from the evaluation's records beside the result.
    ev = p.parent / ("ev_" + p.stem[len("result_"):])
    r["subtasks_total"] = sum(len(json.loads(e.read_text())["subtasks"]) for e in ev.glob("episode_*/episode.json"))
    rows.append(r)
rows.sort(key=lambda r: (r["task"], r["generated"]))
(out / "results.json").write_text("".join(json.dumps(r) + "\n" for r in rows))
md = ["| task | data | episodes | frames | success (of evaluated) | subtasks ended | train s | loss (held out) |",
      "|---|---|---:|---:|---:|---:|---:|---:|"]
for r in rows:
    data = "source alone (replays)" if r["arm"] == "source" else f"source + {r['generated']} generated"
    rate = 100.0 * r["successes"] / max(1, r["evaluated"])
    md.append(f"| {r['task']} | {data} | {r['episodes_in_data']} | {r['frames']} | {rate:.0f} % ({r['successes']}/{r['evaluated']}) | "
              f"{r['subtasks_done']} of {r['subtasks_total']} | {r['train_seconds']:.0f} | {r['loss']:.1e} ({r['held_out_loss']:.1e}) |")
(out / "results.md").write_text("\n".join(md) + "\n")
print("\n".join(md))
# The plot: success (solid) and the share of subtasks ended (dashed) against the number of
# generated demonstrations (0: the source alone).
tasks = list(dict.fromkeys(r["task"] for r in rows))
xs = sorted({r["generated"] for r in rows})
W, H, L, B = 640, 400, 60, 50
def x_of(n):
    i = xs.index(n)
    return L + i * (W - L - 20) / max(1, len(xs) - 1)
def y_of(p):
    return H - B - p * (H - B - 30)
colors = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e"]
svg = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{H}" font-family="sans-serif" font-size="12">',
       f'<rect width="{W}" height="{H}" fill="white"/>',
       f'<text x="{W/2}" y="18" text-anchor="middle" font-size="14">State-based BC, {rows[0]["evaluated"] if rows else 0} episodes: success (solid), subtasks ended (dashed)</text>']
for p in (0, 0.25, 0.5, 0.75, 1.0):
    svg.append(f'<line x1="{L}" y1="{y_of(p)}" x2="{W-20}" y2="{y_of(p)}" stroke="#ddd"/>')
    svg.append(f'<text x="{L-8}" y="{y_of(p)+4}" text-anchor="end">{int(p*100)} %</text>')
for n in xs:
    svg.append(f'<text x="{x_of(n)}" y="{H-B+18}" text-anchor="middle">{"source alone" if n == 0 else "+" + str(n)}</text>')
for k, t in enumerate(tasks):
    pts = sorted((r["generated"], r["successes"] / max(1, r["evaluated"])) for r in rows if r["task"] == t)
    ended = sorted((r["generated"], r["subtasks_done"] / max(1, r["subtasks_total"])) for r in rows if r["task"] == t)
    c = colors[k % len(colors)]
    svg.append('<polyline fill="none" stroke="%s" stroke-width="2" points="%s"/>' % (c, " ".join(f"{x_of(n)},{y_of(p)}" for n, p in pts)))
    svg.append('<polyline fill="none" stroke="%s" stroke-width="1.5" stroke-dasharray="5,4" points="%s"/>' % (c, " ".join(f"{x_of(n)},{y_of(p)}" for n, p in ended)))
    for n, p in pts:
        svg.append(f'<circle cx="{x_of(n)}" cy="{y_of(p)}" r="4" fill="{c}"/>')
    svg.append(f'<text x="{L+10}" y="{40+16*k}" fill="{c}">{t}</text>')
svg.append(f'<text x="{W/2}" y="{H-8}" text-anchor="middle">training data</text></svg>')
(out / "results.svg").write_text("\n".join(svg) + "\n")
EOF
log "results: $OUT/results.md, $OUT/results.svg"
