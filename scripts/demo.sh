#!/usr/bin/env bash
# Sets up everything and runs the main job on the embedded sample data.
# Today that is the most complete pipeline that exists: check the machine (doctor), then
# simulate and render the built-in scene's cameras (RGB + depth + contact sheet, and an
# H.264 clip through ffmpeg) with real MuJoCo physics and EGL rendering.
# Outputs land in ./dexjoco-work/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

"$ROOT/scripts/setup.sh"
cargo build --release --locked -q
BIN="$ROOT/target/release/dexjoco-data"

"$BIN" doctor
# Stills of every camera after the objects have fallen onto the table (1.2 s simulated),
# with depth and a contact sheet; then a 2 s H.264 clip of the fall from the front camera.
"$BIN" render --depth --steps 600
"$BIN" render --video --steps 1000 --camera front --quality fast
# The embedded sample demonstrations (datasets/demos, scripted on the reference scenes):
# validated into the episode store, then their dataset statistics and norm stats.
"$BIN" ingest datasets/demos
"$BIN" stats --dataset
# The language-generalization analysis and success tables on the shipped EXAMPLE
# evaluation outputs (made up by a script, not results).
"$BIN" stats --language-eval --success-table
echo "done: see dexjoco-work/ingest/, dexjoco-work/stats/ and dexjoco-work/render/ (tabletop_contact_sheet.png, tabletop_front.mp4)" >&2
