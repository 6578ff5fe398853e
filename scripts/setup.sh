#!/usr/bin/env bash
# Sets up everything dexjoco-data needs on a Debian 12 machine with the Rust toolchain:
#   1. Debian packages for offscreen rendering (Mesa EGL), video (ffmpeg) and g++ (the
#      meshoptimizer crate);
#   2. MuJoCo 3.17.0's shared library, taken from the `mujoco==3.17.0` wheel on PyPI
#      into .deps/mujoco/lib (git-ignored);
#   3. with --python: the cached Python venv of the real readers used by the tests
#      (outside the repo, under ${XDG_CACHE_HOME:-~/.cache}/dexjoco-data/), and Debian's
#      slurm-wlm and munge for the Slurm test (its daemons are not started);
#   4. with --warp: the Python venv of the Warp batch renderer (`--renderer warp`):
#      mujoco, mujoco-warp and warp-lang as scripts/warp-requirements.txt pins them, in
#      ${XDG_CACHE_HOME:-~/.cache}/dexjoco-data/venv-warp-<mujoco-warp version>/, where
#      dexjoco-data looks for it (path also in .deps/warp-python-path).
# Idempotent: a second run only checks. Source it or run it; it prints what it does.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
MUJOCO_VERSION="3.17.0"
MUJOCO_DIR="$ROOT/.deps/mujoco/lib"
# g++: meshoptimizer (the light geometry) is C++, built by the meshopt crate.
DEB_PACKAGES=(libegl1 libegl-mesa0 libgl1-mesa-dri ffmpeg g++)

log() { printf '\033[1m[setup]\033[0m %s\n' "$*" >&2; }

want_python=0 want_warp=0
for arg in "$@"; do
  case "$arg" in
    --python) want_python=1 ;;
    --warp) want_warp=1 ;;
    -h|--help) sed -n '2,14p' "$0"; exit 0 ;;
    *) echo "setup.sh: unknown argument $arg" >&2; exit 2 ;;
  esac
done

# --- 1. Debian packages ------------------------------------------------------------
missing=()
for p in "${DEB_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# --- Python (needed for the wheel download and the test venv) ------------------------
find_python() {
  local c
  # Preference: $DEXJOCO_BASE_PYTHON, then Python 3.12 (on PATH or from pyenv), then any
  # Python >= 3.10 on PATH.
  for c in "${DEXJOCO_BASE_PYTHON:-}" python3.12 "$HOME"/.pyenv/versions/3.12*/bin/python3 \
           python3.11 python3.13 python3.10 python3; do
    [ -n "$c" ] || continue
    if command -v "$c" >/dev/null 2>&1 && "$c" -c 'import sys; assert sys.version_info >= (3, 10)' 2>/dev/null; then
      command -v "$c"; return 0
    fi
  done
  return 1
}
apt_install() {
  if [ "$(id -u)" = 0 ]; then
    log "installing Debian packages: $*"
    DEBIAN_FRONTEND=noninteractive apt-get update -qq >/dev/null
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null
  elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then
    log "installing Debian packages with sudo: $*"
    sudo DEBIAN_FRONTEND=noninteractive apt-get update -qq >/dev/null
    sudo DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@" >/dev/null
  else
    echo "error: missing Debian packages: $*" >&2
    echo "hint: run as root, or: sudo apt-get install $*" >&2
    exit 1
  fi
}
PYTHON="$(find_python)" || PYTHON=""
# pip fetches the MuJoCo wheel; venv makes the test environment. Debian's own Python
# has them in separate packages.
if [ -z "$PYTHON" ] || ! "$PYTHON" -c 'import pip, venv, ensurepip' 2>/dev/null; then
  apt_install python3 python3-pip python3-venv
  PYTHON="$(find_python)" || { echo "error: no Python >= 3.10 found (set DEXJOCO_BASE_PYTHON)" >&2; exit 1; }
fi

if ((${#missing[@]})); then
  apt_install "${missing[@]}"
fi

# --- Slurm and MUNGE (tests only) ----------------------------------------------------
# The Slurm test runs its own throwaway cluster (scripts/slurm/local-cluster.sh), so the
# packages' own services must not start: while they are installed, a policy-rc.d forbids
# service starts (unless the machine already has one, as Docker images do).
if ((want_python)); then
  slurm_missing=()
  for p in slurm-wlm munge; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || slurm_missing+=("$p")
  done
  if ((${#slurm_missing[@]})); then
    policy=/usr/sbin/policy-rc.d as_root=()
    [ "$(id -u)" = 0 ] || as_root=(sudo -n)
    if [ ! -e "$policy" ] && "${as_root[@]}" true 2>/dev/null; then
      trap '"${as_root[@]}" rm -f "$policy"' EXIT
      printf '#!/bin/sh\nexit 101\n' | "${as_root[@]}" tee "$policy" >/dev/null
      "${as_root[@]}" chmod 755 "$policy"
      apt_install "${slurm_missing[@]}"
      "${as_root[@]}" rm -f "$policy"; trap - EXIT
    else
      apt_install "${slurm_missing[@]}"
    fi
  fi
fi

# --- 2. MuJoCo shared library (and its licences) from the PyPI wheel -----------------
MUJOCO_LICENSES=("$ROOT/.deps/mujoco/LICENSE" "$ROOT/.deps/mujoco/LICENSES_THIRD_PARTY.md")
if [ ! -f "$MUJOCO_DIR/libmujoco.so.$MUJOCO_VERSION" ] || [ ! -f "${MUJOCO_LICENSES[0]}" ] \
   || [ ! -f "${MUJOCO_LICENSES[1]}" ]; then
  log "fetching mujoco==$MUJOCO_VERSION wheel for libmujoco.so.$MUJOCO_VERSION and its licences"
  tmp="$(mktemp -d)"
  trap 'rm -rf "$tmp"' EXIT
  "$PYTHON" -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 \
    --implementation cp --platform manylinux_2_28_"$(uname -m)" \
    "mujoco==$MUJOCO_VERSION" -d "$tmp"
  mkdir -p "$MUJOCO_DIR.tmp"
  "$PYTHON" - "$tmp"/mujoco-*.whl "$MUJOCO_DIR.tmp" "$MUJOCO_VERSION" <<'PY'
import sys, zipfile, shutil, os
whl, out, ver = sys.argv[1:4]
wanted = {
    f"mujoco/libmujoco.so.{ver}": os.path.join(out, f"libmujoco.so.{ver}"),
    f"mujoco-{ver}.dist-info/licenses/LICENSE": os.path.join(out, "LICENSE"),
    f"mujoco-{ver}.dist-info/licenses/LICENSES_THIRD_PARTY.md": os.path.join(out, "LICENSES_THIRD_PARTY.md"),
}
with zipfile.ZipFile(whl) as z:
    for name, dest in wanted.items():
        with z.open(name) as src, open(dest, "wb") as dst:
            shutil.copyfileobj(src, dst)
PY
  mv "$MUJOCO_DIR.tmp/LICENSE" "$MUJOCO_DIR.tmp/LICENSES_THIRD_PARTY.md" "$tmp/"
  ln -sf "libmujoco.so.$MUJOCO_VERSION" "$MUJOCO_DIR.tmp/libmujoco.so"
  rm -rf "$MUJOCO_DIR"; mkdir -p "$(dirname "$MUJOCO_DIR")"; mv "$MUJOCO_DIR.tmp" "$MUJOCO_DIR"
  mv "$tmp/LICENSE" "$tmp/LICENSES_THIRD_PARTY.md" "$ROOT/.deps/mujoco/"
  rm -rf "$tmp"; trap - EXIT
fi

# --- 3. The Python venv of real readers (tests only) ---------------------------------
if ((want_python)); then
  req="$ROOT/tests/python/requirements.txt"
  req_no_deps="$ROOT/tests/python/requirements-no-deps.txt"
  hash="$( (cat "$req" "$req_no_deps"; "$PYTHON" -c 'import sys; print(sys.version)') | sha256sum | cut -c1-12)"
  VENV="${XDG_CACHE_HOME:-$HOME/.cache}/dexjoco-data/venv-$hash"
  if [ ! -x "$VENV/bin/python" ] || [ ! -f "$VENV/.complete" ]; then
    log "creating the test venv $VENV (real readers: $(grep -cv '^\s*#' "$req") packages)"
    rm -rf "$VENV"
    "$PYTHON" -m venv "$VENV"
    "$VENV/bin/python" -m pip install -q --upgrade pip
    "$VENV/bin/python" -m pip install -q -r "$req"
    "$VENV/bin/python" -m pip install -q --no-deps -r "$req_no_deps"
    touch "$VENV/.complete"
  fi
  echo "$VENV/bin/python" > "$ROOT/.deps/python-path"

  # imageio-ffmpeg's wheel, for the wheel test's `pip install --no-index` of the
  # `dexjoco-data[ffmpeg]` extra (the version the readers' venv pins).
  ffmpeg_pin="$(grep -E '^imageio-ffmpeg==' "$req")"
  WHEELHOUSE="${XDG_CACHE_HOME:-$HOME/.cache}/dexjoco-data/wheelhouse"
  if ! ls "$WHEELHOUSE"/imageio_ffmpeg-"${ffmpeg_pin#*==}"-*.whl >/dev/null 2>&1; then
    log "downloading $ffmpeg_pin into $WHEELHOUSE"
    "$VENV/bin/python" -m pip download -q --no-deps --only-binary :all: -d "$WHEELHOUSE" "$ffmpeg_pin"
  fi
  echo "$WHEELHOUSE" > "$ROOT/.deps/wheelhouse-path"

  # The DexJoCo reference environments (parity tests) pin numpy 1.26 and Python 3.11:
  # a second, small venv (no torch), from Debian 12's own python3.11 when present.
  ref_req="$ROOT/tests/python/reference-requirements.txt"
  REF_PYTHON="$(command -v python3.11 || true)"
  if [ -z "$REF_PYTHON" ] || ! "$REF_PYTHON" -c 'import venv, ensurepip' 2>/dev/null; then
    REF_PYTHON="$PYTHON"
  fi
  ref_hash="$( (cat "$ref_req"; "$REF_PYTHON" -c 'import sys; print(sys.version)') | sha256sum | cut -c1-12)"
  REF_VENV="${XDG_CACHE_HOME:-$HOME/.cache}/dexjoco-data/venv-reference-$ref_hash"
  if [ ! -x "$REF_VENV/bin/python" ] || [ ! -f "$REF_VENV/.complete" ]; then
    log "creating the reference venv $REF_VENV (the DexJoCo reference environments' pins)"
    rm -rf "$REF_VENV"
    "$REF_PYTHON" -m venv "$REF_VENV"
    "$REF_VENV/bin/python" -m pip install -q --upgrade pip
    "$REF_VENV/bin/python" -m pip install -q -r "$ref_req"
    touch "$REF_VENV/.complete"
  fi
  echo "$REF_VENV/bin/python" > "$ROOT/.deps/reference-python-path"

  # Diffusion Policy has no package: its tests use the real ReplayBuffer class, one file
  # of real-stanford/diffusion_policy at a pinned commit. It goes into the cache (never
  # into the repo), checked by its sha256, from the first source that has it:
  #   1. GitHub (raw.githubusercontent.com), when reachable;
  #   2. ../shared/third_party/diffusion_policy-<commit>/ (the same file beside the
  #      project, for machines that reach only the package registries).
  DP_COMMIT=5ba07ac6661db573af695b419a7947ecb704690f
  DP_SHA256=c8d59f208525ed5c2164b67f85faf8642251d408533eec1639282076a79d80b4
  DP_REL=diffusion_policy/common/replay_buffer.py
  DP_DIR="${XDG_CACHE_HOME:-$HOME/.cache}/dexjoco-data/diffusion_policy-$DP_COMMIT"
  DP_FILE="$DP_DIR/$DP_REL"
  DP_SHARED="${DEXJOCO_THIRD_PARTY:-$ROOT/../shared/third_party}/diffusion_policy-$DP_COMMIT"
  sha_ok() { [ -f "$1" ] && [ "$(sha256sum "$1" | cut -d' ' -f1)" = "$DP_SHA256" ]; }
  if ! sha_ok "$DP_FILE"; then
    mkdir -p "$(dirname "$DP_FILE")"
    log "fetching Diffusion Policy's replay_buffer.py at $DP_COMMIT from GitHub"
    "$VENV/bin/python" - "$DP_COMMIT" "$DP_SHA256" "$DP_FILE" <<'PY' || true
import hashlib, os, sys, urllib.request
commit, sha, dest = sys.argv[1:4]
url = f"https://raw.githubusercontent.com/real-stanford/diffusion_policy/{commit}/diffusion_policy/common/replay_buffer.py"
try:
    data = urllib.request.urlopen(url, timeout=15).read()
except Exception as e:
    sys.exit(f"[setup] GitHub not reachable ({e})")
if hashlib.sha256(data).hexdigest() != sha:
    sys.exit(f"[setup] {url}: unexpected sha256, not used")
tmp = dest + ".tmp"
open(tmp, "wb").write(data)
os.replace(tmp, dest)
PY
    if ! sha_ok "$DP_FILE"; then
      if sha_ok "$DP_SHARED/$DP_REL"; then
        log "taking Diffusion Policy's replay_buffer.py from $DP_SHARED"
        cp "$DP_SHARED/$DP_REL" "$DP_FILE.tmp" && mv "$DP_FILE.tmp" "$DP_FILE"
        if [ -f "$DP_SHARED/LICENSE" ]; then cp "$DP_SHARED/LICENSE" "$DP_DIR/LICENSE"; fi
      elif [ -f "$DP_SHARED/$DP_REL" ]; then
        log "warning: $DP_SHARED/$DP_REL has the wrong sha256; not used"
      fi
    fi
    if ! sha_ok "$DP_FILE"; then
      echo "error: Diffusion Policy's replay_buffer.py (commit $DP_COMMIT, sha256 $DP_SHA256)" >&2
      echo "       could not be fetched from GitHub and is not at $DP_SHARED/$DP_REL" >&2
      echo "hint: put that file (real-stanford/diffusion_policy at $DP_COMMIT, $DP_REL) at" >&2
      echo "      $DP_FILE" >&2
      echo "      or under \$DEXJOCO_THIRD_PARTY/diffusion_policy-$DP_COMMIT/$DP_REL" >&2
      exit 1
    fi
  fi
  echo "$DP_DIR" > "$ROOT/.deps/diffusion-policy-path"
fi

# --- 4. The Warp batch renderer's venv (--warp) --------------------------------------
if ((want_warp)); then
  warp_req="$ROOT/scripts/warp-requirements.txt"
  warp_version="$(sed -n 's/^mujoco-warp==//p' "$warp_req")"
  WARP_VENV="${XDG_CACHE_HOME:-$HOME/.cache}/dexjoco-data/venv-warp-$warp_version"
  warp_hash="$( (cat "$warp_req"; "$PYTHON" -c 'import sys; print(sys.version)') | sha256sum | cut -c1-12)"
  if [ ! -x "$WARP_VENV/bin/python" ] || [ "$(cat "$WARP_VENV/.complete" 2>/dev/null)" != "$warp_hash" ]; then
    log "creating the Warp renderer venv $WARP_VENV ($(tr '\n' ' ' < "$warp_req"))"
    rm -rf "$WARP_VENV"
    "$PYTHON" -m venv "$WARP_VENV"
    "$WARP_VENV/bin/python" -m pip install -q --upgrade pip
    "$WARP_VENV/bin/python" -m pip install -q -r "$warp_req"
    echo "$warp_hash" > "$WARP_VENV/.complete"
  fi
  echo "$WARP_VENV/bin/python" > "$ROOT/.deps/warp-python-path"
fi
log "ready: MuJoCo $MUJOCO_VERSION in .deps/mujoco/lib"
