#!/usr/bin/env bash
# Sets up everything and runs the main job on the embedded sample data: the whole
# pipeline ingest -> generate -> augment -> convert -> stats on the scripted demonstrations in
# datasets/demos, on the built-in scenes (nothing outside the repository is needed),
# with real MuJoCo physics, EGL rendering and ffmpeg. Outputs land in ./dexjoco-work/.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

"$ROOT/scripts/setup.sh"
cargo build --release --locked -q
BIN="$ROOT/target/release/dexjoco-data"

"$BIN" doctor
# (`--overwrite` where a command would refuse to replace what a previous run of this script
# wrote: the script can be run again.)
# Stills of every camera after the objects have fallen onto the table (1.2 s simulated),
# with depth and a contact sheet; then a 2 s H.264 clip of the fall from the front camera.
"$BIN" render --depth --steps 600 --overwrite
"$BIN" render --video --steps 1000 --camera front --quality fast --overwrite
# The embedded sample demonstrations (datasets/demos: one scripted demonstration per task
# (all 11 tasks), made by `dexjoco-data scripted` on the built-in scenes): the first
# episode of each task validated into the episode store. From the stored click_mouse and
# hammer_nail demonstrations, new ones at new object poses (MimicGen-style: subtask
# segments carried to the objects' new poses, run and checked; the report, a figure of
# where the objects were and a sheet of the resets in dexjoco-work/generate/<task>/).
# The stored and the generated episodes are then replayed 4 times each under
# camera/light/table randomization (224 px, fast preset, so it takes minutes on a 2-core
# CPU; `--replays 10` is the reference's count, about 2.5 times as long; drop the size and
# quality flags for the reference's 640 px multisampled look); the contact sheet has one
# row per task. Then converted to LeRobot v3.0 and a Diffusion Policy replay buffer with
# openpi norm stats; dataset statistics of the augmented set, with the replay success
# rates from the augment report.
"$BIN" ingest datasets/demos/*/episode_000000
"$BIN" generate dexjoco-work/ingest/click_mouse --task click_mouse --count 4 --overwrite
"$BIN" generate dexjoco-work/ingest/hammer_nail --task hammer_nail --count 2 --overwrite
"$BIN" augment dexjoco-work/ingest dexjoco-work/generate --replays 4 --size 224 --quality fast
"$BIN" convert --overwrite --merge-bimanual
"$BIN" convert --format diffusion-policy --norm-stats --overwrite --merge-bimanual
# The LeRobot dataset managed: its successful replays kept (augment keeps successes, so
# all of them here; --where takes any per-episode column), then a seeded train/val split
# stratified per task, each a new dataset beside the source.
"$BIN" dataset filter --where 'outcome/success == true' --out dexjoco-work/dataset/successful --overwrite
"$BIN" dataset split dexjoco-work/dataset/successful --splits train=0.9,val=0.1 --out dexjoco-work/dataset/splits --overwrite
"$BIN" stats --dataset dexjoco-work/augment
# A camera pose pool for click_mouse, built the paper's way (least occluded of 2000
# poses sampled on a sphere), with a preview sheet.
"$BIN" cameras --task click_mouse --preview --overwrite
# A picture of every task: the built-in scenes (next to the reference ones when
# ../shared/dexjoco-upstream is present).
"$BIN" render --task all --size 240 --quality fast --overwrite
# The language-generalization analysis and success tables on the shipped EXAMPLE
# evaluation outputs (made up by a script, not results).
"$BIN" stats --language-eval --success-table
echo "done: see dexjoco-work/generate/ (generate_report.md, generate_poses.png), dexjoco-work/augment/ (augment_report.md, contact_sheet.png), dexjoco-work/convert/, dexjoco-work/dataset/, dexjoco-work/stats/, dexjoco-work/cameras/ and dexjoco-work/render/" >&2
