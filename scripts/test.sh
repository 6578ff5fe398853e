#!/usr/bin/env bash
# Sets up everything (Debian packages, MuJoCo, the cached Python venv of real readers)
# and runs every test: formatting, clippy with warnings as errors, and the whole
# workspace's tests (real MuJoCo physics and EGL rendering, real files, real readers).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

"$ROOT/scripts/setup.sh" --python
export DEXJOCO_PYTHON="$(cat "$ROOT/.deps/python-path")"
export DEXJOCO_DIFFUSION_POLICY="${DEXJOCO_DIFFUSION_POLICY:-$(cat "$ROOT/.deps/diffusion-policy-path")}"

echo "== cargo fmt --check" >&2
cargo fmt --all -- --check
echo "== cargo clippy -D warnings" >&2
cargo clippy --workspace --all-targets --locked -q -- -D warnings
echo "== cargo test" >&2
cargo test --workspace --locked "$@"
