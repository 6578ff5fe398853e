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
# Usage: scripts/package.sh [--bin PATH] [--out DIR]
#   --bin PATH   the binary to package (default: target/release/dexjoco-data, built with
#                `cargo build --release --locked` when missing or older than the sources)
#   --out DIR    where the .tar.gz goes (default: dist/)
# Prints the bundle's path. The archive's bytes depend only on its contents (sorted
# names, fixed owner and times), so the same binary gives the same archive.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
MUJOCO_VERSION="3.17.0"
log() { printf '\033[1m[package]\033[0m %s\n' "$*" >&2; }

bin="" out="dist"
while (($#)); do
  case "$1" in
    --bin) bin="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    -h|--help) sed -n '2,22p' "$0"; exit 0 ;;
    *) echo "package.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done

"$ROOT/scripts/setup.sh" >&2
if [ -z "$bin" ]; then
  log "building the release binary"
  cargo build --release --locked >&2
  bin="target/release/dexjoco-data"
fi
[ -x "$bin" ] || { echo "error: $bin is not an executable" >&2; exit 1; }
lib=".deps/mujoco/lib/libmujoco.so.$MUJOCO_VERSION"
for f in "$lib" .deps/mujoco/LICENSE .deps/mujoco/LICENSES_THIRD_PARTY.md; do
  [ -f "$f" ] || { echo "error: $f is missing: run scripts/setup.sh" >&2; exit 1; }
done
if ! readelf -d "$bin" | grep -q 'RUNPATH.*\$ORIGIN/\.\./lib'; then
  echo "error: $bin has no \$ORIGIN/../lib rpath (built without .cargo/config.toml?)" >&2
  exit 1
fi

version="$("$bin" --version | awk '{print $2}')"
arch="$(uname -m)"
name="dexjoco-data-$version-linux-$arch"
mkdir -p "$out"
out="$(cd "$out" && pwd)"
stage="$(mktemp -d)"
trap 'rm -rf "$stage"' EXIT
dir="$stage/$name"
mkdir -p "$dir/bin" "$dir/lib" "$dir/share/dexjoco-data" "$dir/licenses"

log "binary $bin (stripped), libmujoco $MUJOCO_VERSION"
cp "$bin" "$dir/bin/dexjoco-data"
strip "$dir/bin/dexjoco-data"
cp "$lib" "$dir/lib/"
ln -s "libmujoco.so.$MUJOCO_VERSION" "$dir/lib/libmujoco.so"

log "sample data, cluster scripts and container recipes"
cp -r datasets "$dir/share/dexjoco-data/datasets"
find "$dir/share/dexjoco-data/datasets" -name '__pycache__' -prune -exec rm -rf {} +
mkdir -p "$dir/share/dexjoco-data/slurm" "$dir/share/dexjoco-data/deploy"
cp scripts/slurm/augment.sbatch scripts/slurm/submit.sh "$dir/share/dexjoco-data/slurm/"
cp deploy/Dockerfile deploy/dexjoco-data.def "$dir/share/dexjoco-data/deploy/"
cp deploy/BUNDLE-README.md "$dir/README.md"

log "licences: dexjoco-data, MuJoCo, the Rust crates compiled in"
cp LICENSE-MIT LICENSE-APACHE "$dir/licenses/"
cp .deps/mujoco/LICENSE "$dir/licenses/MuJoCo-LICENSE"
cp .deps/mujoco/LICENSES_THIRD_PARTY.md "$dir/licenses/MuJoCo-LICENSES_THIRD_PARTY.md"
cargo metadata --format-version 1 --locked --filter-platform "$(rustc -vV | sed -n 's/^host: //p')" \
  | python3 "$ROOT/scripts/third_party_licenses.py" > "$dir/licenses/THIRD-PARTY-RUST.md"

tarball="$out/$name.tar.gz"
# Reproducible: sorted entries, fixed owner and modification time, no gzip timestamp.
tar --sort=name --owner=0 --group=0 --numeric-owner --mtime='2026-01-01 00:00Z' \
  -C "$stage" -cf - "$name" | gzip -9n > "$tarball.partial"
mv "$tarball.partial" "$tarball"
log "$(du -h "$tarball" | cut -f1) $tarball"
echo "$tarball"
