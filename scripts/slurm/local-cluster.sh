#!/usr/bin/env bash
# Starts and stops a throwaway single-node Slurm cluster (munged + slurmctld + slurmd)
# whose every file lives under one folder DIR: slurm.conf, the MUNGE key and socket,
# state, spool, logs and pid files. Nothing is written to /etc, /var or /run. Used by the
# test suite to run scripts/slurm/augment.sbatch for real; needs root and Debian's
# `slurm-wlm` and `munge` packages (scripts/setup.sh --python installs them).
#
#   local-cluster.sh start DIR   bring the cluster up (DIR must be absent, empty, or a
#                                leftover of an earlier run, which is stopped and wiped
#                                first); waits until the node is idle, then prints on
#                                stdout the one variable Slurm's commands need:
#                                  export SLURM_CONF=DIR/slurm.conf
#                                (also written to DIR/env). Progress goes to stderr.
#   local-cluster.sh stop DIR    cancel every job, stop exactly the daemons this script
#                                started for DIR (pids recorded under DIR, each checked
#                                to be ours before it is signalled), wait for them to
#                                exit, and remove DIR. Safe to repeat; a no-op when DIR
#                                does not exist.
#   local-cluster.sh status DIR  print sinfo and squeue for the cluster.
#
# Environment: LOCAL_SLURM_TIMEOUT (seconds to wait for the node to be idle, default 30).
# The cluster's TCP ports are picked at random among free ones below the ephemeral range.
set -euo pipefail

MARKER=.local-slurm-cluster # file in DIR saying "this folder belongs to this script"
ENV_TAG=LOCAL_SLURM_CLUSTER_DIR # env var given to every daemon: finds strays by DIR

log() { printf '[local-cluster] %s\n' "$*" >&2; }
die() { printf '[local-cluster] error: %s\n' "$*" >&2; exit 1; }
usage() { sed -n '2,22p' "$0" >&2; exit 2; }

# --- processes --------------------------------------------------------------------------

# The environment and the command line of process $1 (one entry a line / space-separated);
# empty for kernel threads, processes of other users, processes that just exited.
proc_env() { { tr '\0' '\n' <"/proc/$1/environ"; } 2>/dev/null || true; }
proc_cmd() { { tr '\0' ' ' <"/proc/$1/cmdline"; } 2>/dev/null || true; }

# True when PID is a live (not zombie) process of this cluster: one this script started
# for $DIR (its environment carries ENV_TAG=$DIR, or it is munged/slurmctld/slurmd with a
# file under $DIR on its command line), or a process of one of the cluster's jobs (its
# environment has SLURM_CONF=$DIR/slurm.conf and a SLURM_JOB_ID). A recycled pid fails.
ours() {
  local pid=$1 state env cmd
  [[ "$pid" =~ ^[0-9]+$ ]] && [ -r "/proc/$pid/stat" ] || return 1
  state="$(sed -E 's/^.*\) ([A-Za-z]).*$/\1/' "/proc/$pid/stat" 2>/dev/null)" || return 1
  [ "$state" != Z ] && [ "$state" != X ] || return 1
  env="$(proc_env "$pid")"
  if grep -qxF "$ENV_TAG=$DIR" <<<"$env"; then return 0; fi
  if grep -qxF "SLURM_CONF=$DIR/slurm.conf" <<<"$env" && grep -q '^SLURM_JOB_ID=' <<<"$env"; then
    return 0
  fi
  cmd="$(proc_cmd "$pid")"
  [[ "${cmd%% *}" =~ (^|/)(munged|slurmctld|slurmd|slurmstepd)$ && "$cmd" == *" "*"$DIR/"* ]]
}

# Every live process of this cluster (see ours) other than the pid-file ones that could
# only be found by their command line: slurmscriptd and slurmstepd (they inherit ENV_TAG)
# and the jobs' processes. One grep over all environments, then ours on the candidates.
strays() {
  local pid
  {
    # (grep fails on kernel threads' and vanished processes' files: not an error here)
    grep -lzxF -- "$ENV_TAG=$DIR" /proc/[0-9]*/environ || true
    grep -lzxF -- "SLURM_CONF=$DIR/slurm.conf" /proc/[0-9]*/environ || true
  } 2>/dev/null | sed -nE 's#^/proc/([0-9]+)/environ$#\1#p' | sort -un |
    while read -r pid; do
      if [ "$pid" != "$$" ] && [ "$pid" != "$BASHPID" ] && ours "$pid"; then echo "$pid"; fi
    done
}

# Sends SIGTERM to the given pids that are ours, waits up to $2 seconds for them to go,
# then SIGKILLs what is left. $1: a space-separated list of pids.
terminate() {
  local pids=() pid left i
  for pid in $1; do ours "$pid" && pids+=("$pid"); done
  ((${#pids[@]})) || return 0
  kill -TERM "${pids[@]}" 2>/dev/null || true
  for ((i = 0; i < $2 * 10; i++)); do
    left=()
    for pid in "${pids[@]}"; do ours "$pid" && left+=("$pid"); done
    ((${#left[@]})) || return 0
    sleep 0.1
  done
  log "still running ${2}s after SIGTERM, sending SIGKILL: ${left[*]}"
  kill -KILL "${left[@]}" 2>/dev/null || true
  for ((i = 0; i < 50; i++)); do
    left=()
    for pid in "${pids[@]}"; do ours "$pid" && left+=("$pid"); done
    ((${#left[@]})) || return 0
    sleep 0.1
  done
  die "could not stop processes ${left[*]}"
}

# Waits up to 3 s for the given pids to vanish from /proc (not even zombies left, so that
# `pgrep` right after stop shows nothing; their parent, init, reaps them).
wait_reaped() {
  local pid i alive
  for ((i = 0; i < 30; i++)); do
    alive=0
    for pid in $1; do [ -e "/proc/$pid" ] && alive=1; done
    ((alive)) || return 0
    sleep 0.1
  done
}

pidfile_pid() { if [ -f "$1" ]; then tr -dc '0-9' <"$1"; fi; }

# --- stop -------------------------------------------------------------------------------

stop_cluster() {
  [ -e "$DIR" ] || return 0
  [ -d "$DIR" ] || die "$DIR is not a folder"
  if [ ! -f "$DIR/$MARKER" ] && [ -n "$(ls -A "$DIR")" ]; then
    die "$DIR was not made by local-cluster.sh (no $MARKER in it); not touching it"
  fi
  local ctld slurmd munged
  ctld="$(pidfile_pid "$DIR/run/slurmctld.pid")"
  slurmd="$(pidfile_pid "$DIR/run/slurmd.pid")"
  munged="$(pidfile_pid "$DIR/munge/munged.pid")"

  # Jobs first, while the daemons can still end them cleanly.
  if [ -n "$ctld" ] && ours "$ctld" && [ -n "$slurmd" ] && ours "$slurmd"; then
    local jobs i
    jobs="$(SLURM_CONF="$DIR/slurm.conf" timeout 10 squeue -h -o %A 2>/dev/null || true)"
    if [ -n "$jobs" ]; then
      log "cancelling jobs: $(tr '\n' ' ' <<<"$jobs")"
      # shellcheck disable=SC2086 # one job id per word
      SLURM_CONF="$DIR/slurm.conf" timeout 10 scancel $jobs 2>/dev/null || true
      for ((i = 0; i < 100; i++)); do
        [ -z "$(SLURM_CONF="$DIR/slurm.conf" timeout 5 squeue -h -o %A 2>/dev/null || true)" ] && break
        sleep 0.1
      done
    fi
  fi
  # The Slurm daemons, then MUNGE (the Slurm daemons talk to it while shutting down),
  # then anything left over (job steps, job processes of a crashed slurmd).
  local before rest
  before="$(strays)"
  terminate "$ctld $slurmd" 15
  terminate "$munged" 10
  rest="$(strays)"
  terminate "$rest" 5
  wait_reaped "$ctld $slurmd $munged $before $rest"
  rm -rf "$DIR"
}

# --- start ------------------------------------------------------------------------------

# Prints N free TCP ports (no socket of any state uses them), chosen at random below the
# kernel's ephemeral port range so that outgoing connections cannot take them meanwhile.
free_ports() {
  local n=$1 lo hi used=" " f port out=()
  read -r lo _ </proc/sys/net/ipv4/ip_local_port_range 2>/dev/null || lo=32768
  hi=$((lo - 1)); lo=$((hi > 20000 ? 10000 : 1024))
  for f in /proc/net/tcp /proc/net/tcp6; do
    [ -r "$f" ] || continue
    while read -r _ local _; do
      [[ "$local" == *:* ]] && used+="$((16#${local##*:})) "
    done <"$f"
  done
  while ((${#out[@]} < n)); do
    port=$((lo + (RANDOM * 32768 + RANDOM) % (hi - lo + 1)))
    [[ "$used" == *" $port "* ]] && continue
    used+="$port "; out+=("$port")
  done
  echo "${out[@]}"
}

# The node's hardware line for slurm.conf, as slurmd itself will report it (so that the
# node is not drained for a mismatch), with RealMemory lowered by 10% (lower is allowed).
node_hardware() {
  local line mem
  line="$(slurmd -C 2>/dev/null | head -n1)" || line=""
  if [[ "$line" =~ (CPUs=[0-9]+.*ThreadsPerCore=[0-9]+).*RealMemory=([0-9]+) ]]; then
    mem=$((BASH_REMATCH[2] * 9 / 10))
    echo "${BASH_REMATCH[1]} RealMemory=$((mem > 1 ? mem : 1))"
  else
    echo "CPUs=$(nproc) RealMemory=1"
  fi
}

write_conf() {
  local node=$1 ctld_port=$2 slurmd_port=$3
  cat >"$DIR/slurm.conf" <<EOF
# Single-node test cluster made by scripts/slurm/local-cluster.sh; all files under
# $DIR.
ClusterName=localtest
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
# Everything runs as root: no 'slurm' user, no file ownership to arrange.
SlurmUser=root
SlurmdUser=root
# MUNGE at its own socket, not the system one (used by auth/munge and cred/munge).
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$DIR/munge/munge.socket
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/run/slurmctld.pid
SlurmdPidFile=$DIR/run/slurmd.pid
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
# No cgroups (containers rarely allow them): track job processes through /proc, no task
# binding, no accounting, no job completion log, no MPI.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
# One job per CPU; memory is not a consumable resource.
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
# No mail program on test machines.
MailProg=/bin/true
# A node that was DOWN comes back as soon as its slurmd registers.
ReturnToService=2
# Cancelled jobs get SIGKILL 5 s after SIGTERM (default 30 s), for a quick stop.
KillWait=5
# Start a waiting job (the next shard, the finalize job) about 1 s after a job ends
# rather than 2 s (the default batch_sched_delay is 3 s).
SchedulerParameters=batch_sched_delay=0
NodeName=$node NodeAddr=127.0.0.1 NodeHostname=$node $(node_hardware) State=UNKNOWN
PartitionName=local Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
}

# Starts the three daemons (each daemonizes itself and writes its pid file), with
# ENV_TAG=$DIR in their environment and stdio away from the caller's pipes.
launch() {
  local sock=$DIR/munge/munge.socket i
  if ! ours "$(pidfile_pid "$DIR/munge/munged.pid")"; then # (kept on a retry)
    env "$ENV_TAG=$DIR" munged --socket="$sock" --key-file="$DIR/munge/munge.key" \
      --pid-file="$DIR/munge/munged.pid" --log-file="$DIR/log/munged.log" \
      --seed-file="$DIR/munge/munged.seed" </dev/null >>"$DIR/log/munged.out" 2>&1 ||
      { log "munged failed to start"; return 1; }
  fi
  for ((i = 0; i < 50; i++)); do
    munge -S "$sock" -n 2>/dev/null | unmunge -S "$sock" >/dev/null 2>&1 && break
    sleep 0.1
  done
  env "$ENV_TAG=$DIR" SLURM_CONF="$DIR/slurm.conf" slurmctld -f "$DIR/slurm.conf" \
    </dev/null >>"$DIR/log/slurmctld.out" 2>&1 || { log "slurmctld failed to start"; return 1; }
  env "$ENV_TAG=$DIR" SLURM_CONF="$DIR/slurm.conf" slurmd -f "$DIR/slurm.conf" \
    </dev/null >>"$DIR/log/slurmd.out" 2>&1 || { log "slurmd failed to start"; return 1; }
}

# Waits until sinfo shows the node idle; false after the timeout or when a daemon died.
wait_idle() {
  local node=$1 deadline state="" f
  deadline=$((SECONDS + ${LOCAL_SLURM_TIMEOUT:-30}))
  while ((SECONDS < deadline)); do
    for f in run/slurmctld.pid run/slurmd.pid munge/munged.pid; do
      if [ -f "$DIR/$f" ] && ! ours "$(pidfile_pid "$DIR/$f")"; then
        log "${f#*/} is there but its daemon died"
        return 1
      fi
    done
    state="$(SLURM_CONF="$DIR/slurm.conf" timeout 3 sinfo -h -n "$node" -o %t 2>/dev/null || true)"
    [ "$state" = idle ] && return 0
    sleep 0.2
  done
  log "node $node not idle after ${LOCAL_SLURM_TIMEOUT:-30}s (state: ${state:-no answer})"
  return 1
}

show_logs() {
  local f
  SLURM_CONF="$DIR/slurm.conf" timeout 5 scontrol show node >&2 2>/dev/null || true
  for f in "$DIR"/log/*; do
    [ -s "$f" ] || continue
    printf '\n===== %s (last 40 lines) =====\n' "$f" >&2
    tail -n 40 "$f" >&2
  done
}

start_cluster() {
  [ "$(id -u)" = 0 ] || die "needs root (slurmd runs jobs as their user; munged and slurmd are set up for root)"
  local c
  for c in munged munge unmunge slurmctld slurmd sinfo squeue scancel sbatch; do
    command -v "$c" >/dev/null || die "$c not found; install Debian's slurm-wlm and munge (scripts/setup.sh --python)"
  done
  if [ -e "$DIR" ]; then
    if [ -f "$DIR/$MARKER" ]; then
      log "$DIR is left from an earlier run; stopping it first"
      stop_cluster
    elif [ -n "$(ls -A "$DIR" 2>/dev/null)" ]; then
      die "$DIR exists and is not empty"
    fi
  fi
  mkdir -p "$DIR"
  : >"$DIR/$MARKER"
  mkdir -p "$DIR"/{munge,state,spool,log,run}
  chmod 0755 "$DIR" "$DIR/munge"
  # munged insists that every folder above its socket be searchable by everyone.
  local p=$DIR
  while [ "$p" != / ]; do
    p="$(dirname "$p")"
    [ "$(( 8#$(stat -c %a "$p") & 1 ))" = 1 ] ||
      { rm -rf "$DIR"; die "munged needs every folder above its socket searchable by all (chmod o+x $p), or use a DIR elsewhere (e.g. under /tmp)"; }
  done
  # A fresh MUNGE key, readable by root only (munged refuses anything laxer).
  (umask 077 && head -c 1024 /dev/urandom >"$DIR/munge/munge.key")
  chmod 0400 "$DIR/munge/munge.key"

  local node t0=$SECONDS attempt ports f
  node="$(hostname -s)"
  for attempt in 1 2 3; do
    read -r -a ports <<<"$(free_ports 2)"
    write_conf "$node" "${ports[0]}" "${ports[1]}"
    if launch && wait_idle "$node"; then
      printf 'export SLURM_CONF=%q\n' "$DIR/slurm.conf" >"$DIR/env"
      log "up in $((SECONDS - t0))s: node $node idle, ports ${ports[0]}/${ports[1]}, folder $DIR"
      cat "$DIR/env"
      return 0
    fi
    if ((attempt < 3)) &&
      grep -qs 'Address already in use' "$DIR/log/slurmctld.log" "$DIR/log/slurmd.log"; then
      log "port taken meanwhile; retrying with other ports"
      # (slurmd lingers on SIGTERM without a controller: no need to wait long for it)
      terminate "$(pidfile_pid "$DIR/run/slurmctld.pid") $(pidfile_pid "$DIR/run/slurmd.pid")" 2
      terminate "$(strays | grep -vx "$(pidfile_pid "$DIR/munge/munged.pid")" || true)" 5
      for f in "$DIR"/log/slurm{ctld,d}.{log,out}; do
        if [ -e "$f" ]; then mv "$f" "$f.attempt$attempt"; fi
      done
      rm -rf "$DIR"/state/* "$DIR"/spool/* "$DIR"/run/*
      continue
    fi
    break
  done
  log "the cluster did not come up; logs follow"
  show_logs
  stop_cluster
  exit 1
}

# --- main -------------------------------------------------------------------------------

[ $# = 2 ] || usage
[ -n "$2" ] || usage
DIR="$(realpath -m -- "$2")"
[ "$DIR" != / ] || die "refusing DIR=/"
case "$1" in
  start) start_cluster ;;
  stop) stop_cluster; log "stopped; $DIR removed" ;;
  status)
    [ -f "$DIR/slurm.conf" ] || die "no cluster in $DIR"
    SLURM_CONF="$DIR/slurm.conf" sinfo
    SLURM_CONF="$DIR/slurm.conf" squeue ;;
  *) usage ;;
esac
