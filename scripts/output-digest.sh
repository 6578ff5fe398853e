#!/usr/bin/env bash
# Runs a small sample pipeline with one binary and prints the SHA-256 of every output file,
# so that a restructuring can be checked to leave output bytes unchanged:
#   scripts/output-digest.sh target/debug/dexjoco-data > after.txt && diff before.txt after.txt
# Covers ingest (raw + MCAP), export to MCAP, scripted, augment (96 px, fast), convert to
# LeRobot v3.0 / v2.1 / Diffusion Policy with norm stats, and stats --dataset. Timestamps and
# durations in reports, and the build identity (version + git commit, recorded since #24),
# are filtered out: they change run to run, or commit to commit, by design.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BIN="$(realpath "${1:-$ROOT/target/debug/dexjoco-data}")"
# A fixed folder: paths are recorded in outputs (MCAP `source` metadata, store manifests).
W="${DIGEST_DIR:-/tmp/dexjoco-output-digest}"
rm -rf "$W"; mkdir -p "$W"
trap 'rm -rf "$W"' EXIT; [ -n "${KEEP:-}" ] && trap - EXIT
cd "$W"
run() { "$BIN" -q -j 2 --work-dir "$W/work" "$@" >/dev/null 2>"$W/last.log" || { cat "$W/last.log" >&2; exit 1; }; }
demos="$ROOT/datasets/demos"
run ingest "$demos/click_mouse/episode_000000" "$demos/bimanual_assembly/episode_000000"
run export --to mcap
run ingest "$W/work/export" --out "$W/mcap-store"
run scripted --task pinch_tongs --episodes 1 --out "$W/scripted"
run augment "$W/work/ingest" --replays 2 --size 96 --quality fast
run convert --overwrite --merge-bimanual
run convert --merge-bimanual --format lerobot-v2.1 --out "$W/work/v21" --overwrite
run convert --format diffusion-policy --norm-stats --merge-bimanual --overwrite --out "$W/work/dp"
run stats --dataset "$W/work/augment"
cd "$W"
find . -type f ! -name last.log -print0 | LC_ALL=C sort -z | while IFS= read -r -d '' f; do
  case "$f" in
    *.json|*.md|*.txt|*.jsonl)
      # reports carry wall-clock times and durations; strip those lines
      printf '%s  %s\n' "$(grep -vE '"(started|finished|created|elapsed|seconds|duration|wall|time)[a-z_]*"|"dexjoco_data"|git [0-9a-f]{7,}|[0-9.]+ ?s\b|[0-9]+:[0-9]{2}' "$f" | sha256sum | cut -c1-16)" "$f (filtered)" ;;
    *) printf '%s  %s\n' "$(sha256sum < "$f" | cut -c1-16)" "$f" ;;
  esac
done
