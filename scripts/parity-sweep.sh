#!/usr/bin/env bash
# Runs the tests that compare our simulation with the DexJoCo reference code under each
# arithmetic setting of the reference side that this CPU can run (numpy's SIMD loops and
# OpenBLAS's kernels: tests/python/reference_arithmetic.py), so that a change which
# would pass on one CPU and fail on another is caught on one machine. The test suite
# itself runs them under one pinned setting (avx2); see docs/testing.md.
#
#   scripts/parity-sweep.sh [SETTING ...]     # default: every setting this CPU runs
#
# Needs the venvs scripts/setup.sh --python makes. About 10 minutes per setting on 2 cores.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

export DEXJOCO_PYTHON="${DEXJOCO_PYTHON:-$(cat "$ROOT/.deps/python-path")}"
export DEXJOCO_REFERENCE_PYTHON="${DEXJOCO_REFERENCE_PYTHON:-$(cat "$ROOT/.deps/reference-python-path")}"

flags="$(grep -m1 '^flags' /proc/cpuinfo || true)"
has() { for f in "$@"; do [[ " $flags " == *" $f "* ]] || return 1; done; }
settings=("$@")
if ((${#settings[@]} == 0)); then
  settings=(native baseline sandybridge)
  has avx2 fma && settings+=(avx2)
  if has avx512f avx512bw avx512vl avx512dq; then
    settings+=(avx512 avx512-numpy avx512-blas)
  else
    echo "[sweep] this CPU has no AVX-512: the avx512 settings are left out (run them on one that has)" >&2
  fi
fi

cargo test --locked -p dexjoco-augment --test reference_parity --test augment --no-run -q
cargo test --locked -p dexjoco-sim --test reference_predicates --no-run -q
failed=()
# pipefail: a pipeline fails when cargo test does, whatever grep shows.
for s in "${settings[@]}"; do
  echo "[sweep] == DEXJOCO_REFERENCE_ARITHMETIC=$s" >&2
  if ! DEXJOCO_REFERENCE_ARITHMETIC="$s" cargo test --locked -q -p dexjoco-augment \
      --test reference_parity --test augment reference -- --nocapture 2>&1 \
      | grep -E '^\||^The reference|does not succeed|succeeds at|test result|panicked|FAILED' \
    || ! DEXJOCO_REFERENCE_ARITHMETIC="$s" cargo test --locked -q -p dexjoco-sim \
      --test reference_predicates 2>&1 | grep -E 'test result|panicked|FAILED'; then
    failed+=("$s")
  fi
done
if ((${#failed[@]})); then
  echo "[sweep] FAILED under: ${failed[*]}" >&2
  exit 1
fi
echo "[sweep] passed under: ${settings[*]}" >&2
