#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, to try `plantview farm submit --scheduler slurm`
# without a cluster: munged, slurmctld and slurmd on free loopback ports, their configuration,
# state and logs in one directory, all run as root (as tests/test_farm.cpp's SlurmCluster does).
#
#   scripts/slurm_local.sh start    # starts the daemons, waits until the node is idle, and prints
#                                   # the line to use: export SLURM_CONF=DIR/slurm.conf
#   scripts/slurm_local.sh status   # the daemons' process ids and the node's state
#   scripts/slurm_local.sh stop     # stops the daemons by process id and removes DIR
#
# DIR is $PLANTVIEW_SLURM_DIR, default /tmp/plantview-slurm. Needs root and Debian's slurm-wlm
# and munge. Only the export line goes to stdout (`eval "$(scripts/slurm_local.sh start)"`);
# messages go to stderr. Exit status: 0 done (status: running), 1 failure (status: not running),
# 2 usage.
set -euo pipefail

DIR="${PLANTVIEW_SLURM_DIR:-/tmp/plantview-slurm}"
CONF="$DIR/slurm.conf"
DAEMONS=(munged slurmctld slurmd)   # started in this order, stopped in the reverse

say() { echo "slurm_local: $*" >&2; }

# The process id recorded for daemon $1, printed only while that process runs and is that daemon
# (a stale file or a reused id is not ours to signal).
live_pid() {
  local file="$DIR/pids/$1" pid
  [[ -f "$file" ]] || return 1
  pid="$(<"$file")"
  [[ "$pid" =~ ^[0-9]+$ && -r "/proc/$pid/comm" ]] || return 1
  [[ "$(<"/proc/$pid/comm")" == "$1" ]] || return 1
  echo "$pid"
}

any_running() {
  local d
  for d in "${DAEMONS[@]}"; do live_pid "$d" >/dev/null && return 0; done
  return 1
}

# A TCP port nothing on this machine listens on.
free_port() {
  local port
  for _ in $(seq 1 200); do
    port=$((20000 + RANDOM % 40000))
    if [[ -z "$(ss -Htan "( sport = :$port )" 2>/dev/null)" ]]; then echo "$port"; return 0; fi
  done
  say "no free port found"; return 1
}

# Starts daemon $1 (the rest: its arguments) in a session of its own, output to DIR/$1.out,
# and records its process id (setsid runs it in place: this shell's children lead no group).
spawn() {
  local name="$1"; shift
  setsid "$@" </dev/null >"$DIR/$name.out" 2>&1 &
  echo $! >"$DIR/pids/$name"
}

stop() {
  local i name pid
  for ((i = ${#DAEMONS[@]} - 1; i >= 0; i--)); do
    name="${DAEMONS[i]}"
    pid="$(live_pid "$name")" || continue
    kill -TERM "$pid" 2>/dev/null || true
    for _ in $(seq 1 100); do [[ -d "/proc/$pid" ]] || break; sleep 0.1; done
    if [[ -d "/proc/$pid" ]]; then say "$name ($pid) still runs after 10 s: SIGKILL"; kill -KILL "$pid" 2>/dev/null || true; fi
    say "stopped $name ($pid)"
  done
  # Only a directory this script made (it holds its pids/ folder) is removed.
  if [[ -d "$DIR/pids" ]]; then rm -rf "$DIR"; fi
}

start() {
  if [[ "$(id -u)" != 0 ]]; then say "run as root: slurmctld and slurmd run as root here"; exit 1; fi
  local tool
  for tool in munged slurmctld slurmd sbatch squeue sinfo ss setsid; do
    command -v "$tool" >/dev/null 2>&1 || { say "$tool is not installed (Debian: slurm-wlm, munge)"; exit 1; }
  done
  if any_running; then say "already running in $DIR (scripts/slurm_local.sh stop first)"; exit 1; fi
  if [[ -e "$DIR" && ! -d "$DIR/pids" ]]; then say "$DIR exists and is not this script's: set PLANTVIEW_SLURM_DIR"; exit 1; fi
  rm -rf "$DIR"
  mkdir -p "$DIR/munge" "$DIR/state" "$DIR/spool" "$DIR/pids"
  chmod 700 "$DIR/munge"
  head -c 1024 /dev/urandom >"$DIR/munge/munge.key"
  chmod 600 "$DIR/munge/munge.key"

  local m="$DIR/munge"
  spawn munged munged -F -f -S "$m/munge.sock" --key-file="$m/munge.key" \
    --log-file="$m/munged.log" --pid-file="$m/munged.pid" --seed-file="$m/munged.seed"
  for _ in $(seq 1 100); do [[ -S "$m/munge.sock" ]] && break; sleep 0.05; done
  if [[ ! -S "$m/munge.sock" ]]; then say "munged did not start:"; cat "$DIR/munged.out" >&2; stop; exit 1; fi

  local ctld_port slurmd_port
  ctld_port="$(free_port)"; slurmd_port="$(free_port)"
  while [[ "$slurmd_port" == "$ctld_port" ]]; do slurmd_port="$(free_port)"; done
  cat >"$CONF" <<EOF
ClusterName=plantviewlocal
SlurmctldHost=localhost
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$m/munge.sock
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
ReturnToService=2
SchedulerType=sched/backfill
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/slurmctld.pid
SlurmdPidFile=$DIR/slurmd.pid
SlurmctldLogFile=$DIR/slurmctld.log
SlurmdLogFile=$DIR/slurmd.log
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$(nproc) State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
  export SLURM_CONF="$CONF"
  spawn slurmctld slurmctld -D -i -f "$CONF"
  spawn slurmd slurmd -D -N localhost -f "$CONF"

  local state=""
  for _ in $(seq 1 150); do
    state="$(sinfo -h -o %t 2>/dev/null || true)"
    [[ "$state" == idle* ]] && break
    sleep 0.2
  done
  if [[ "$state" != idle* ]]; then
    say "the node did not become idle in 30 s (state: '${state}'); the logs:"
    tail -n 20 "$DIR/slurmctld.log" "$DIR/slurmd.log" "$DIR"/*.out >&2 2>/dev/null || true
    stop; exit 1
  fi
  say "one-node cluster running in $DIR (munged $(live_pid munged), slurmctld $(live_pid slurmctld), slurmd $(live_pid slurmd)); node idle"
  say "use it from this shell with the line below; stop it with: scripts/slurm_local.sh stop"
  echo "export SLURM_CONF=$CONF"
}

status() {
  local d pid up=0
  for d in "${DAEMONS[@]}"; do
    if pid="$(live_pid "$d")"; then echo "$d: running ($pid)"; up=$((up + 1)); else echo "$d: not running"; fi
  done
  if ((up == ${#DAEMONS[@]})); then
    echo "node: $(SLURM_CONF="$CONF" sinfo -h -o '%n %t %c CPUs' 2>/dev/null || echo unknown)"
    echo "export SLURM_CONF=$CONF"
    return 0
  fi
  return 1
}

case "${1:-}" in
  start) start ;;
  stop) stop ;;
  status) status ;;
  *) echo "usage: scripts/slurm_local.sh start|stop|status   (directory: \$PLANTVIEW_SLURM_DIR, default /tmp/plantview-slurm)" >&2; exit 2 ;;
esac
