# Shared by scripts/bench-policy.sh and scripts/bench-generate-policy.sh (sourced, not run):
# needs PY (the test venv's python), BIN, SOURCE_SEED, SCENE_ARGS and log().

# Frames of the raw episodes under $1 (their action arrays' rows; hidden folders skipped).
frames() {
  "$PY" - "$1" <<'PYEOF'
import sys, pathlib, zarr
n = 0
for z in pathlib.Path(sys.argv[1]).rglob("replay.zarr"):
    if not any(p.startswith(".") for p in z.relative_to(sys.argv[1]).parts):
        n += zarr.open(str(z), mode="r")["data"]["action"].shape[0]
print(n)
PYEOF
}

# A free TCP port on 127.0.0.1.
free_port() {
  "$PY" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}

# One source demonstration of task $1 in $2/source/$1: the first seed from SOURCE_SEED
# whose scripted plan succeeds (kept if there).
scripted_source() {
  local task=$1 dir=$2 s
  [ -d "$dir/source/$task/episode_000000" ] && return 0
  for s in $(seq "$SOURCE_SEED" $((SOURCE_SEED + 9))); do
    rm -rf "$dir/source"
    if "$BIN" -q scripted --task "$task" --episodes 1 --seed "$s" "${SCENE_ARGS[@]}" --out "$dir/source" >/dev/null 2>&1; then
      log "$task: source demonstration from scripted seed $s"
      return 0
    fi
  done
  log "$task: no scripted plan succeeded from seeds $SOURCE_SEED to $((SOURCE_SEED + 9))"
  return 1
}
