#!/usr/bin/env bash
# `dataset filter` / `dataset split` against lerobot-edit-dataset (the test venv's
# lerobot) on the same dataset, written by lerobot's own writer: EPISODES episodes of
# LENGTH..LENGTH+21 frames, one SIZExSIZE AV1 camera (lerobot's default encoding).
# Operations: delete every 10th episode (ours: `filter --episodes ... --drop`), a 0.8/0.2
# split (ours seeded and stratified; lerobot's given the same episode lists), and a merge
# of the source with lerobot's filtered copy (both written by lerobot), and a re-encode of
# every video to H.264 crf 23, GOP 2 (ours with -j JOBS, lerobot's with --operation.num_workers
# JOBS).
# Wall time and peak memory (GNU time's maximum resident set) of each, side by side, in
# OUT/results.md. Reported, not asserted.
#
#   scripts/bench-dataset.sh [OUT]
#
# Environment: EPISODES (300), LENGTH (100), SIZE (64), JOBS (2),
# BIN (target/release/dexjoco-data).
# Needs the test venv (scripts/setup.sh --python) and GNU time (/usr/bin/time).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="$(mkdir -p "${1:-$ROOT/bench-dataset}" && cd "${1:-$ROOT/bench-dataset}" && pwd)"
EPISODES="${EPISODES:-300}"
LENGTH="${LENGTH:-100}"
SIZE="${SIZE:-64}"
JOBS="${JOBS:-2}"
BIN="${BIN:-$ROOT/target/release/dexjoco-data}"
PY="$(cat "$ROOT/.deps/python-path")"
EDIT="$(dirname "$PY")/lerobot-edit-dataset"
log() { printf '[bench-dataset] %s\n' "$*" >&2; }
[ -x "$BIN" ] || { log "no $BIN: cargo build --release"; exit 1; }
[ -x "$EDIT" ] || { log "no lerobot-edit-dataset in the test venv: scripts/setup.sh --python"; exit 1; }
[ -x /usr/bin/time ] || { log "no /usr/bin/time (apt install time)"; exit 1; }
export HF_HUB_OFFLINE=1

src="$OUT/source"
if [ ! -f "$src/meta/info.json" ]; then
  log "writing $EPISODES episodes with lerobot's writer"
  rm -rf "$src"
  "$PY" "$ROOT/tests/python/lerobot_small_dataset.py" "$src" "$EPISODES" "$SIZE" "$LENGTH" >/dev/null 2>"$OUT/source.log"
fi

# Runs a command under GNU time; prints "seconds peak_MB".
measure() {
  /usr/bin/time -f '%e %M' -o "$OUT/time.txt" "$@" >"$OUT/last.log" 2>&1 || { cat "$OUT/last.log" >&2; exit 1; }
  read -r s kb <"$OUT/time.txt"
  echo "$s $((kb / 1024))"
}

drop="$(seq 0 10 $((EPISODES - 1)) | paste -sd, -)"
rm -rf "$OUT"/ours_* "$OUT"/theirs_*
log "delete every 10th episode"
ours_f="$(measure "$BIN" -q dataset filter "$src" --episodes "$drop" --drop --out "$OUT/ours_filter")"
theirs_f="$(measure "$EDIT" --repo_id local/source --root "$src" --new_repo_id local/edited \
  --new_root "$OUT/theirs_filter" --operation.type delete_episodes --operation.episode_indices "[$drop]")"
log "split 0.8 / 0.2"
ours_s="$(measure "$BIN" -q dataset split "$src" --splits train=0.8,val=0.2 --out "$OUT/ours_split")"
lists="$("$PY" -c 'import json,sys; s=json.load(open(sys.argv[1]))["splits"]; print(json.dumps(s))' "$OUT/ours_split/split.json")"
theirs_s="$(measure "$EDIT" --repo_id local/source --root "$src" --new_repo_id local/edited \
  --new_root "$OUT/theirs_split" --operation.type split --operation.splits "$lists")"

log "merge the source and lerobot's filtered copy"
ours_m="$(measure "$BIN" -q dataset merge "$src" "$OUT/theirs_filter" --out "$OUT/ours_merge")"
theirs_m="$(measure "$EDIT" --new_repo_id local/merged --new_root "$OUT/theirs_merge" \
  --operation.type merge --operation.repo_ids "['local/a', 'local/b']" \
  --operation.roots "['$src', '$OUT/theirs_filter']")"

log "re-encode every video to H.264 (crf 23, GOP 2)"
ours_r="$(measure "$BIN" -q -j "$JOBS" dataset reencode "$src" --codec h264 --crf 23 --gop 2 --out "$OUT/ours_reencode")"
theirs_r="$(measure "$EDIT" --repo_id local/source --root "$src" --new_repo_id local/edited \
  --new_root "$OUT/theirs_reencode" --operation.type reencode_videos --operation.num_workers "$JOBS" \
  --operation.rgb_encoder.vcodec h264 --operation.rgb_encoder.crf 23 --operation.rgb_encoder.g 2)"

row() {
  local op=$1 ours=$2 theirs=$3
  read -r os om <<<"$ours"
  read -r ts tm <<<"$theirs"
  printf '| %s | %s | %s | %s | %s | %s |\n' "$op" "$os" "$ts" \
    "$("$PY" -c "print(f'{$ts / max($os, 0.01):.1f}x')")" "$om" "$tm"
}
{
  echo "| operation ($EPISODES episodes, $SIZE px) | ours s | lerobot-edit-dataset s | speed-up | ours peak MB | lerobot peak MB |"
  echo "|---|---:|---:|---:|---:|---:|"
  row "delete every 10th episode" "$ours_f" "$theirs_f"
  row "split 0.8 / 0.2" "$ours_s" "$theirs_s"
  row "merge (300 + 270 episodes)" "$ours_m" "$theirs_m"
  row "re-encode to H.264 ($JOBS workers)" "$ours_r" "$theirs_r"
} >"$OUT/results.md"
cat "$OUT/results.md"
