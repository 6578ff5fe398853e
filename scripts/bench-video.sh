#!/usr/bin/env bash
# Measures the video encodings augment and convert can use, for both costs users pay
# (issue #38): the encoder's CPU per frame while augmenting, and the read time per
# random item when a LeRobot v3.0 dataset is loaded for training; with the dataset's size
# and the image quality against the rendered frames (PSNR).
#
# For each size: the sample demo is augmented once losslessly (`--crf 0`: libx264rgb,
# the rendered RGB frames bit for bit), then once per x264 candidate (preset x keyframe
# interval; crf 21, the DexJoCo recorder's; same seed, so the same frames). Per candidate:
# x264's CPU per frame (augment's own profile: the encoder processes' CPU seconds over
# the frames), the videos' bytes, PSNR (RGB, every frame) against the lossless run. At
# the first size each candidate's augment output is also converted (stream copy) and
# read at random with lerobot 0.6.1 (tests/python/lerobot_random_read.py; torchcodec
# and pyav), beside two datasets convert re-encodes from x264's long-interval default
# (`--reencode`, GOP 2: H.264 and AV1, lerobot's own encoding, which the DexJoCo reference
# converter uses). SVT-AV1 as augment's encoder is measured on the lossless frames with
# ffmpeg (`-benchmark` CPU, 1 thread as augment's encoders run).
#
# Usage: scripts/bench-video.sh [--bin PATH] [--task T] [--replays N] [--sizes "224 640"]
#                               [--items N] [--out DIR]
# Defaults: target/release/dexjoco-data, hammer_nail, 2 replays, sizes 224 640, 60 items,
# dexjoco-work/bench-video. Prints a Markdown table per size; JSON lines in <out>/rows.jsonl.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
bin="target/release/dexjoco-data" task="hammer_nail" replays=2 sizes="224 640" items=60
out="dexjoco-work/bench-video"
while (($#)); do
  case "$1" in
    --bin) bin="$2"; shift 2 ;;
    --task) task="$2"; shift 2 ;;
    --replays) replays="$2"; shift 2 ;;
    --sizes) sizes="$2"; shift 2 ;;
    --items) items="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    -h|--help) sed -n '2,24p' "$0"; exit 0 ;;
    *) echo "bench-video.sh: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
[ -x "$bin" ] || { echo "error: $bin missing: cargo build --release (or --bin PATH)" >&2; exit 1; }
py="$(cat .deps/python-path 2>/dev/null || true)"
[ -x "$py" ] || { echo "error: no readers' venv: run scripts/setup.sh --python" >&2; exit 1; }
log() { printf '\033[1m[bench-video]\033[0m %s\n' "$*" >&2; }
# preset:keyframe-interval (0: x264's own, 250)
candidates="medium:0 medium:10 fast:10 faster:10 veryfast:0 veryfast:30 veryfast:10 veryfast:2 superfast:10 ultrafast:10"
mkdir -p "$out"
rows="$out/rows.jsonl"
: > "$rows"

# PSNR (RGB, average over every frame of every video) of the videos under $1 against $2's.
psnr() {
  local total=0 n=0 v
  while IFS= read -r f; do
    rel="${f#"$1"/}"
    v="$(ffmpeg -hide_banner -nostdin -i "$f" -i "$2/$rel" -lavfi \
      '[0:v]format=gbrp[a];[1:v]format=gbrp[b];[a][b]psnr' -f null - 2>&1 \
      | sed -n 's/.*PSNR.* average:\([0-9.inf]*\).*/\1/p' | tail -1)"
    total="$(python3 -c "print($total + float('$v'))")"; n=$((n + 1))
  done < <(find "$1" -path '*/videos/*.mp4' | sort)
  python3 -c "print(round($total / max($n, 1), 2))"
}
video_bytes() { find "$1" -path '*/videos/*.mp4' -printf '%s\n' | awk '{s+=$1} END {print s}'; }
# x264 CPU ms per frame, from augment's own summary ("encode (x264 CPU) 0.53 ms").
encode_ms() {
  sed -n 's/.*encode (x264 CPU) \([0-9.]*\) ms.*/\1/p' "$1.log" | tail -1
}
# Random-read ms per item (median) of a LeRobot dataset with one backend.
read_ms() {
  "$py" tests/python/lerobot_random_read.py "$1" "$2" "$items" \
    | python3 -c "import json,sys; r=json.load(sys.stdin); print(round(r['ms_median'], 1))"
}
dataset_bytes() { du -sb "$1" | cut -f1; }
row() { # name size cpu_ms video_bytes psnr dataset_bytes torchcodec_ms pyav_ms
  printf '{"candidate":"%s","size":%s,"encode_cpu_ms_per_frame":%s,"video_bytes":%s,"psnr_db":%s,"dataset_bytes":%s,"read_ms_torchcodec":%s,"read_ms_pyav":%s}\n' \
    "$@" >> "$rows"
  printf '| %s | %s | %s | %s | %s | %s | %s |\n' "$1" "$3" "$(($4 / 1000)) kB" "$5" \
    "$([ "$6" = null ] && echo - || echo "$(($6 / 1000)) kB")" \
    "$([ "$7" = null ] && echo - || echo "$7")" "$([ "$8" = null ] && echo - || echo "$8")"
}

first_size="${sizes%% *}"
for size in $sizes; do
  d="$out/$size"
  rm -rf "$d"; mkdir -p "$d"
  "$bin" -q ingest "datasets/demos/$task" --out "$d/ingest" >/dev/null
  aug() { # out-dir extra-flags...
    local o="$1"; shift
    "$bin" -q augment "$d/ingest" --out "$o" --replays "$replays" --size "$size" --quality fast "$@" > "$o.log"
  }
  log "$size px: lossless reference run"
  aug "$d/lossless" --crf 0 --keyframe-interval 0
  echo
  echo "### $size px ($task, $replays replays, one camera)"
  echo
  echo "| encoding | x264 CPU ms / frame | videos | PSNR dB | dataset | ms / random item, torchcodec | ms / random item, pyav |"
  echo "|---|---:|---:|---:|---:|---:|---:|"
  for c in $candidates; do
    preset="${c%%:*}" g="${c##*:}"
    name="augment x264 $preset, keyframes $([ "$g" = 0 ] && echo 250 || echo "$g"); convert stream copy"
    log "$size px: $name"
    aug "$d/x264-$preset-g$g" --x264-preset "$preset" --keyframe-interval "$g"
    cpu="$(encode_ms "$d/x264-$preset-g$g")"
    vb="$(video_bytes "$d/x264-$preset-g$g")"
    p="$(psnr "$d/x264-$preset-g$g" "$d/lossless")"
    db=null tc=null pa=null
    if [ "$size" = "$first_size" ]; then
      "$bin" -q convert "$d/x264-$preset-g$g" --out "$d/ds-$preset-g$g" >/dev/null
      db="$(dataset_bytes "$d/ds-$preset-g$g")"
      tc="$(read_ms "$d/ds-$preset-g$g" torchcodec)"; pa="$(read_ms "$d/ds-$preset-g$g" pyav)"
    fi
    row "$name" "$size" "$cpu" "$vb" "$p" "$db" "$tc" "$pa"
  done
  if [ "$size" = "$first_size" ]; then
    for codec in h264 av1; do
      name="augment x264 medium, keyframes 250; convert --reencode --video-codec $codec (GOP 2)"
      log "$size px: $name"
      "$bin" -q convert "$d/x264-medium-g0" --out "$d/ds-reencode-$codec" --reencode --video-codec "$codec" >/dev/null
      db="$(dataset_bytes "$d/ds-reencode-$codec")"
      row "$name" "$size" null 0 null "$db" "$(read_ms "$d/ds-reencode-$codec" torchcodec)" "$(read_ms "$d/ds-reencode-$codec" pyav)"
    done
  fi
  # SVT-AV1 as the augment encoder (lerobot's settings: crf 30, GOP 2; presets 12 and 8),
  # on the lossless frames, one thread; CPU from ffmpeg's -benchmark (decode of the
  # lossless input measured alone and taken off).
  decode_cpu=0 frames=0
  while IFS= read -r f; do
    u="$(ffmpeg -hide_banner -nostdin -benchmark -threads 1 -i "$f" -f null - 2>&1 | sed -n 's/.*utime=\([0-9.]*\)s stime=\([0-9.]*\)s.*/\1 \2/p')"
    decode_cpu="$(python3 -c "a,b='$u'.split(); print($decode_cpu + float(a) + float(b))")"
    frames=$((frames + $(ffprobe -v error -count_packets -select_streams v:0 -show_entries stream=nb_read_packets -of csv=p=0 "$f")))
  done < <(find "$d/lossless" -path '*/videos/*.mp4' | sort)
  for av1preset in 12 8; do
    name="augment SVT-AV1 preset $av1preset, crf 30, GOP 2 (lerobot's encoding)"
    log "$size px: $name"
    rm -rf "$d/av1-$av1preset"; cp -r "$d/lossless" "$d/av1-$av1preset"
    cpu=0
    while IFS= read -r f; do
      rel="${f#"$d/lossless"/}"
      u="$(ffmpeg -hide_banner -nostdin -y -benchmark -threads 1 -i "$f" -c:v libsvtav1 -crf 30 -preset "$av1preset" -g 2 \
        -svtav1-params lp=1 -pix_fmt yuv420p "$d/av1-$av1preset/$rel" 2>&1 | sed -n 's/.*utime=\([0-9.]*\)s stime=\([0-9.]*\)s.*/\1 \2/p')"
      cpu="$(python3 -c "a,b='$u'.split(); print($cpu + float(a) + float(b))")"
    done < <(find "$d/lossless" -path '*/videos/*.mp4' | sort)
    ms="$(python3 -c "print(round(1e3 * ($cpu - $decode_cpu) / $frames, 3))")"
    row "$name" "$size" "$ms" "$(video_bytes "$d/av1-$av1preset")" "$(psnr "$d/av1-$av1preset" "$d/lossless")" null null null
  done
done
log "rows: $rows"
