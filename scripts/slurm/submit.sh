#!/usr/bin/env bash
# Submits a sharded `dexjoco-data augment` (or `generate`) to Slurm: a job array of N
# shards (scripts/slurm/augment.sbatch with --array=0-(N-1), each task running
# `STAGE ARGS... --shard auto`) and a finalize job (`STAGE ARGS...`, no --shard) that
# starts only after every shard succeeded (--dependency=afterok:ARRAY) and is cancelled
# by Slurm if any shard fails (--kill-on-invalid-dep=yes).
#
#   scripts/slurm/submit.sh [OPTIONS] N ARGS...
#     e.g. scripts/slurm/submit.sh --wait 4 demo.json --out aug/ --replays 10
#          scripts/slurm/submit.sh --stage generate 8 --task hammer_nail --count 1000 --out gen/
#
#   --stage STAGE   the command the jobs run: augment (default) or generate.
#   --wait          wait until the finalize job and every shard have ended (polling
#                   scontrol: sbatch's own --wait polls after 2, 8, 32 s, slow for short
#                   jobs, and exits 0 for a finalize job cancelled for a failed shard);
#                   exit 0 only if every shard and the finalize job completed with exit
#                   code 0, else print the jobs' states and exit 1. Ctrl-C cancels both.
#   --logs DIR      write the jobs' stdout/stderr to DIR/STAGE-ARRAYID_TASK.log and
#                   DIR/finalize-JOBID.log (default: sbatch's, slurm-*.out in the current
#                   folder).
#   --sbatch OPT    one more option for both sbatch calls (repeatable), e.g.
#                   --sbatch --cpus-per-task=4 --sbatch --time=2:00:00
#
# Prints "ARRAY_JOB_ID FINALIZE_JOB_ID" on stdout. DEXJOCO_BIN names the binary the jobs
# run; by default, run from a release bundle (share/dexjoco-data/slurm/submit.sh), the
# bundle's own bin/dexjoco-data, else dexjoco-data on PATH. The bundle must lie on a file
# system every node sees. SUBMIT_POLL_SECONDS sets the --wait poll interval (default 1).
set -euo pipefail

HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
SCRIPT="$HERE/augment.sbatch"
# Slurm copies the batch script to each node's spool, so the script cannot find the
# bundle by its own path: the binary is resolved here and exported to the jobs.
if [ -z "${DEXJOCO_BIN:-}" ] && [[ "$HERE" == */share/dexjoco-data/slurm ]] \
   && [ -x "$HERE/../../../bin/dexjoco-data" ]; then
  DEXJOCO_BIN="$(cd "$HERE/../../../bin" && pwd)/dexjoco-data"
fi
export DEXJOCO_BIN="${DEXJOCO_BIN:-dexjoco-data}"
log() { printf '[submit] %s\n' "$*" >&2; }
usage() { sed -n '2,27p' "$0" >&2; exit 2; }

wait_=0 logs="" extra=() stage=augment
while (($#)); do
  case "$1" in
    --wait) wait_=1; shift ;;
    --stage) (($# >= 2)) || usage; stage="$2"; shift 2 ;;
    --logs) (($# >= 2)) || usage; logs="$2"; shift 2 ;;
    --sbatch) (($# >= 2)) || usage; extra+=("$2"); shift 2 ;;
    -h|--help) usage ;;
    *) break ;;
  esac
done
if (($# < 1)) || ! [[ "$1" =~ ^[1-9][0-9]*$ ]]; then usage; fi
case "$stage" in augment|generate) ;; *) log "--stage: augment or generate, not '$stage'"; exit 2 ;; esac
# The batch script runs this stage (sbatch exports the submitting environment).
export DEXJOCO_STAGE="$stage"
n=$1; shift

# Submitted from inside another Slurm job, these would leak into the jobs' environment
# and make the finalize job look like a shard.
unset SLURM_ARRAY_TASK_ID SLURM_ARRAY_TASK_COUNT SLURM_ARRAY_JOB_ID \
  SLURM_ARRAY_TASK_MIN SLURM_ARRAY_TASK_MAX SLURM_ARRAY_TASK_STEP

out_array=() out_final=()
if [ -n "$logs" ]; then
  mkdir -p "$logs"
  logs="$(cd "$logs" && pwd)"
  out_array=(--output="$logs/$stage-%A_%a.log")
  out_final=(--output="$logs/finalize-%j.log")
fi

array="$(sbatch --parsable --array="0-$((n - 1))" --job-name="dexjoco-$stage" \
  "${out_array[@]}" "${extra[@]}" "$SCRIPT" "$@")"
array="${array%%;*}"
final="$(sbatch --parsable --dependency="afterok:$array" --kill-on-invalid-dep=yes \
  --job-name="dexjoco-$stage-finalize" "${out_final[@]}" "${extra[@]}" "$SCRIPT" "$@")" || {
  log "submitting the finalize job failed; cancelling the shards (job $array)"
  scancel "$array" || true
  exit 1
}
final="${final%%;*}"
log "submitted $n shards as array job $array; finalize job $final runs after them"
echo "$array $final"
((wait_)) || exit 0

# --- --wait ---------------------------------------------------------------------------
trap 'log "interrupted; cancelling jobs $array and $final"; scancel "$array" "$final" 2>/dev/null; exit 130' INT TERM

# One line per job record of job $1 (one per array task): its JobId, ArrayTaskId,
# JobState, Reason and ExitCode fields.
states() {
  scontrol -o show job "$1" 2>/dev/null | awk '{ l = ""
    for (i = 1; i <= NF; i++) if ($i ~ /^(JobId|ArrayTaskId|JobState|Reason|ExitCode)=/) l = l " " $i
    print substr(l, 2) }'
}
# How many of the lines on stdin are jobs that completed with exit code 0.
count_ok() { grep -E 'JobState=COMPLETED( |$)' | grep -cE 'ExitCode=0:0( |$)' || true; }
terminal='JobState=(COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY|PREEMPTED|BOOT_FAIL|DEADLINE)( |$)'

misses=0
while :; do
  s="$(states "$final")"
  if [ -z "$s" ]; then # slurmctld busy or restarting, or the job record is gone
    ((++misses < 10)) || { log "Slurm no longer answers about finalize job $final"; exit 1; }
  else
    misses=0
    grep -qE "$terminal" <<<"$s" && break
  fi
  sleep "${SUBMIT_POLL_SECONDS:-1}"
done

# The finalize job ends early when a shard fails; the other shards may still run.
while shards="$(states "$array")" && [ -n "$shards" ] && grep -qvE "$terminal" <<<"$shards"; do
  sleep "${SUBMIT_POLL_SECONDS:-1}"
done
ok=1
[ "$(count_ok <<<"$s")" = 1 ] || ok=0
[ "$(count_ok <<<"$shards")" = "$n" ] || ok=0
if ((ok)); then
  log "all $n shards and the finalize job completed"
  exit 0
fi
log "FAILED: not every job completed with exit code 0"
log "shards (array job $array):"
while IFS= read -r l; do printf "    %s\n" "$l"; done <<<"$shards" >&2
log "finalize:"
while IFS= read -r l; do printf "    %s\n" "$l"; done <<<"$s" >&2
exit 1
