#!/usr/bin/env bash
# Sets up everything (Debian packages, MuJoCo, the cached Python venvs of real readers
# and of the Warp renderer)
# and runs every test: formatting, clippy with warnings as errors, and the whole
# workspace's tests (real MuJoCo physics and EGL rendering, real files, real readers).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

"$ROOT/scripts/setup.sh" --python --warp
export DEXJOCO_PYTHON="$(cat "$ROOT/.deps/python-path")"
export DEXJOCO_DIFFUSION_POLICY="${DEXJOCO_DIFFUSION_POLICY:-$(cat "$ROOT/.deps/diffusion-policy-path")}"
export DEXJOCO_REFERENCE_PYTHON="$(cat "$ROOT/.deps/reference-python-path")"
export DEXJOCO_WARP_PYTHON="$(cat "$ROOT/.deps/warp-python-path")"

# A clean build gains nothing from incremental compilation's caches (gigabytes of them).
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"

echo "== cargo fmt --check" >&2
cargo fmt --all -- --check
echo "== cargo clippy -D warnings" >&2
cargo clippy --workspace --all-targets --locked -q -- -D warnings
echo "== cargo test (every test binary runs, even after a failure)" >&2
# --no-fail-fast keeps going past a failing test binary; the summary at the end lists
# every failed test and every test binary that had one.
log="$(mktemp)"
trap 'rm -f "$log"' EXIT
set +e
cargo test --workspace --locked --no-fail-fast "$@" 2>&1 | tee "$log"
status=${PIPESTATUS[0]}
set -e
if [ "$status" -ne 0 ]; then
  echo >&2
  echo "== FAILED (cargo test exit $status). Failing tests:" >&2
  grep -E '^test .* \.\.\. FAILED$' "$log" | sed -E 's/^test (.*) \.\.\. FAILED$/  \1/' | sort -u >&2 || true
  echo "== Test binaries with failures:" >&2
  grep -E '^error: [0-9]+ targets? failed:' -A100 "$log" | grep -E '^\s+`' >&2 || true
  exit "$status"
fi
echo "== all tests passed" >&2
