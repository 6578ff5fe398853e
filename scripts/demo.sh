#!/usr/bin/env bash
# Sets up everything and runs the main job on the embedded sample data.
# Today that is the most complete pipeline that exists: check the machine (doctor), then
# render the built-in scene's cameras (RGB + depth + contact sheet) through MuJoCo and EGL.
# Outputs land in ./dexjoco-work/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

"$ROOT/scripts/setup.sh"
cargo build --release --locked -q
BIN="$ROOT/target/release/dexjoco-data"

"$BIN" doctor
"$BIN" render --depth
echo "done: see dexjoco-work/render/tabletop_contact_sheet.png" >&2
