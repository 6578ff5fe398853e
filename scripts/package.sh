#!/usr/bin/env bash
# Writes the relocatable release bundle dist/dexjoco-data-<version>-linux-<arch>.tar.gz:
#
#   dexjoco-data-<version>-linux-<arch>/
#     bin/dexjoco-data                 stripped; finds lib/ through its $ORIGIN/../lib rpath
#     lib/libmujoco.so.<mujoco>        MuJoCo's shared library (from the PyPI wheel)
#     share/dexjoco-data/datasets/     the sample data (demos/, examples/)
#     share/dexjoco-data/slurm/        augment.sbatch, submit.sh (run the bundle's binary)
#     share/dexjoco-data/deploy/       Dockerfile, dexjoco-data.def (Apptainer)
#     licenses/                        dexjoco-data's, MuJoCo's (and its third parties'),
#                                      every Rust crate compiled in
#     README.md                        what the bundle is, what the machine needs
#
# or, with --wheel, the Python wheel dist/dexjoco_data-<version>-py3-none-manylinux_2_28_x86_64.whl
# (maturin, `bindings = "bin"`, see pyproject.toml) that installs the same layout into a
# Python environment: <env>/bin/dexjoco-data, <env>/lib/libmujoco.so.<mujoco>,
# <env>/share/dexjoco-data/ (datasets/, slurm/, deploy/, licenses/).
#
# Usage: scripts/package.sh [--bin PATH] [--out DIR]
#        scripts/package.sh --wheel [--profile dev|release] [--native] [--out DIR]
#   --bin PATH   the binary to package (default: target/release/dexjoco-data, built with
#                `cargo build --release --locked` when missing or older than the sources)
#   --out DIR    where the .tar.gz or .whl goes (default: dist/)
#   --wheel      build the wheel with maturin (pinned in scripts/wheel-requirements.txt,
#                installed into ~/.cache/dexjoco-data/venv-wheel-<hash>), linked against
#                glibc 2.28 through zig (`maturin build --zig`): RHEL 8 and newer
#   --profile P  cargo profile of the wheel's binary (default: release)
#   --native     link with this machine's toolchain instead of zig (the wheel then needs
#                this machine's glibc; quick when target/ already holds the build)
# Prints the bundle's (or wheel's) path. The archive's bytes depend only on its contents
# (sorted names, fixed owner and times), so the same binary gives the same archive.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
MUJOCO_VERSION="3.17.0"
log() { printf '\033[1m[package]\033[0m %s\n' "$*" >&2; }

bin="" out="dist" wheel=0 profile="release" native=0
while (($#)); do
  case "$1" in
    --bin) bin="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --wheel) wheel=1; shift ;;
    --profile) profile="$2"; shift 2 ;;
    --native) native=1; shift ;;
    -h|--help) sed -n '2,36p' "$0"; exit 0 ;;
    *) echo "package.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done

"$ROOT/scripts/setup.sh" >&2
lib=".deps/mujoco/lib/libmujoco.so.$MUJOCO_VERSION"
for f in "$lib" .deps/mujoco/LICENSE .deps/mujoco/LICENSES_THIRD_PARTY.md; do
  [ -f "$f" ] || { echo "error: $f is missing: run scripts/setup.sh" >&2; exit 1; }
done
mkdir -p "$out"
out="$(cd "$out" && pwd)"

# Copies what the bundle and the wheel carry beside the binary into $1 (their
# share/dexjoco-data) and the licences into $2.
stage_share() {
  local share="$1" licenses="$2"
  mkdir -p "$share/slurm" "$share/deploy" "$licenses"
  cp -r datasets "$share/datasets"
  find "$share/datasets" -name '__pycache__' -prune -exec rm -rf {} +
  cp scripts/slurm/augment.sbatch scripts/slurm/submit.sh "$share/slurm/"
  cp deploy/Dockerfile deploy/dexjoco-data.def "$share/deploy/"
  cp LICENSE-MIT LICENSE-APACHE "$licenses/"
  cp .deps/mujoco/LICENSE "$licenses/MuJoCo-LICENSE"
  cp .deps/mujoco/LICENSES_THIRD_PARTY.md "$licenses/MuJoCo-LICENSES_THIRD_PARTY.md"
  cargo metadata --format-version 1 --locked --filter-platform "$(rustc -vV | sed -n 's/^host: //p')" \
    | python3 "$ROOT/scripts/third_party_licenses.py" > "$licenses/THIRD-PARTY-RUST.md"
}

# The wheel: maturin builds the binary and packs it with target/wheel-data (pyproject.toml).
if ((wheel)); then
  req="$ROOT/scripts/wheel-requirements.txt"
  hash="$( (cat "$req"; python3 -c 'import sys; print(sys.version)') | sha256sum | cut -c1-12)"
  venv="${XDG_CACHE_HOME:-$HOME/.cache}/dexjoco-data/venv-wheel-$hash"
  if [ ! -f "$venv/.complete" ]; then
    log "creating the wheel-building venv $venv (maturin, ziglang, auditwheel)"
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/python" -m pip install -q -r "$req"
    touch "$venv/.complete"
  fi
  data="$ROOT/target/wheel-data"
  rm -rf "$data"
  mkdir -p "$data/data/lib"
  cp "$lib" "$data/data/lib/"
  stage_share "$data/data/share/dexjoco-data" "$data/data/share/dexjoco-data/licenses"
  # A file of its own in share/dexjoco-data lets `pip uninstall` remove the folder whole.
  cp deploy/WHEEL-SHARE-README.md "$data/data/share/dexjoco-data/README.md"
  args=(build --locked --profile "$profile" --auditwheel skip --out "$out")
  [ "$profile" = release ] && args+=(--strip)
  if ((native)); then
    args+=(--compatibility linux)
  else
    args+=(--zig --compatibility manylinux_2_28)
  fi
  log "maturin ${args[*]}"
  PATH="$venv/bin:$PATH" maturin "${args[@]}" >&2
  whl="$(ls -t "$out"/dexjoco_data-*.whl | head -1)"
  # auditwheel reads the program's rpath from where pip puts it: MuJoCo is in the wheel.
  log "auditwheel show: $("$venv/bin/auditwheel" show "$whl" 2>&1 | tr '\n' ' ' | sed 's/  */ /g')"
  log "$(du -h "$whl" | cut -f1) $whl"
  echo "$whl"
  exit 0
fi

if [ -z "$bin" ]; then
  log "building the release binary"
  cargo build --release --locked >&2
  bin="target/release/dexjoco-data"
fi
[ -x "$bin" ] || { echo "error: $bin is not an executable" >&2; exit 1; }
if ! readelf -d "$bin" | grep -q 'RUNPATH.*\$ORIGIN/\.\./lib'; then
  echo "error: $bin has no \$ORIGIN/../lib rpath (built without .cargo/config.toml?)" >&2
  exit 1
fi

version="$("$bin" --version | awk '{print $2}')"
arch="$(uname -m)"
name="dexjoco-data-$version-linux-$arch"
stage="$(mktemp -d)"
trap 'rm -rf "$stage"' EXIT
dir="$stage/$name"
mkdir -p "$dir/bin" "$dir/lib" "$dir/share/dexjoco-data" "$dir/licenses"

log "binary $bin (stripped), libmujoco $MUJOCO_VERSION"
cp "$bin" "$dir/bin/dexjoco-data"
strip "$dir/bin/dexjoco-data"
cp "$lib" "$dir/lib/"
ln -s "libmujoco.so.$MUJOCO_VERSION" "$dir/lib/libmujoco.so"

log "sample data, cluster scripts, container recipes, licences"
stage_share "$dir/share/dexjoco-data" "$dir/licenses"
cp deploy/BUNDLE-README.md "$dir/README.md"

tarball="$out/$name.tar.gz"
# Reproducible: sorted entries, fixed owner and modification time, no gzip timestamp.
tar --sort=name --owner=0 --group=0 --numeric-owner --mtime='2026-01-01 00:00Z' \
  -C "$stage" -cf - "$name" | gzip -9n > "$tarball.partial"
mv "$tarball.partial" "$tarball"
log "$(du -h "$tarball" | cut -f1) $tarball"
echo "$tarball"
