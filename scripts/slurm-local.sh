#!/usr/bin/env bash
# A one-node Slurm cluster on localhost (munged, slurmctld, slurmd) in a fresh temporary folder,
# for trying a collection on Slurm without a cluster, and for the test that does
# (tests/rig/collection_slurm_test.sh). docs/collection.md.
#
#   scripts/slurm-local.sh run [--cpus N] [--mem-mb N] -- COMMAND [ARG...]
#       brings the cluster up, runs COMMAND with SLURM_CONF pointing at it (sbatch, squeue,
#       scancel, sinfo and Snakemake's --slurm all find it), then shuts the daemons down and
#       removes the folder, whatever COMMAND did (also on Ctrl-C). Exits with COMMAND's status.
#   scripts/slurm-local.sh up [--cpus N] [--mem-mb N]
#       brings it up and leaves it running; prints the folder and `export SLURM_CONF=...`.
#   scripts/slurm-local.sh down DIR
#       shuts down the cluster that `up` started in DIR and removes DIR.
#
# Exit status 77 (with the reason on stderr) when the cluster cannot be brought up here: the
# packages are missing (apt-get install slurm-wlm munge), not root (slurmd starts every job as
# its owner, which needs root), or a daemon did not start (its log is printed).
#
# What is generated (nothing outside the folder is read or written; no systemd, no cgroups, so it
# runs inside a container): a random munge key, its own munged socket, slurm.conf with two free
# TCP ports on 127.0.0.1, proctrack/linuxproc, task/none, jobacct_gather/linux (RSS sampled every
# second, and a job over its --mem killed at the sample that finds it so: OverMemoryKill, the
# enforcement a cluster without cgroups has), cons_tres with cores and memory as consumable resources, one partition
# `debug` (default) holding this host, and the completed jobs logged by jobcomp/filetxt in
# DIR/jobcomp.txt (their state, run time, CPUs and memory asked). With slurmdbd and MariaDB
# installed (apt-get install slurmdbd mariadb-server; scripts/setup.sh does) it also keeps
# accounting as a real cluster does: a MariaDB server of its own (data folder, socket and a free
# TCP port on 127.0.0.1, a random password), slurmdbd on another free port, the cluster
# registered with sacctmgr, so `sacct` lists every job with its requests; without them it says
# so and runs without (sacct then answers nothing, and the records are that file).
set -euo pipefail

die77() { echo "slurm-local: cannot bring up the cluster: $*" >&2; exit 77; }

cpus=$(nproc)
# Memory offered to jobs: half of this machine's, by default.
mem_mb=$(( $(awk '/^MemTotal:/ {print $2}' /proc/meminfo) / 2048 ))

parse_size() {
  while [ $# -gt 0 ]; do
    case "$1" in
      --cpus) cpus="$2"; shift 2 ;;
      --mem-mb) mem_mb="$2"; shift 2 ;;
      --) shift; break ;;
      *) echo "slurm-local: unknown option '$1'" >&2; exit 2 ;;
    esac
  done
  rest=("$@")
}

free_port() {
  python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

# Stops what DIR's pid files name (only those processes: never by name), then removes DIR.
down() {
  local dir="$1" pid i
  [ -d "$dir" ] || return 0
  # Jobs still running are cancelled first (slurmstepd outlives a stopped slurmd).
  if [ -s "$dir/run/slurmctld.pid" ]; then
    SLURM_CONF="$dir/slurm.conf" scancel --full --quiet --user="$(id -un)" 2>/dev/null || true
    for i in $(seq 50); do
      [ -z "$(SLURM_CONF="$dir/slurm.conf" squeue -h -t R,CG -o %i 2>/dev/null)" ] && break
      sleep 0.2
    done
  fi
  for f in slurmd.pid slurmctld.pid slurmdbd.pid mariadb.pid munged.pid; do
    [ -s "$dir/run/$f" ] || continue
    pid=$(cat "$dir/run/$f")
    case "$pid" in *[!0-9]*|'') continue ;; esac
    kill -TERM "$pid" 2>/dev/null || continue
    for i in $(seq 100); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -KILL "$pid" 2>/dev/null || true
  done
  rm -rf -- "$dir"
}

up() {
  for b in munged mungekey slurmctld slurmd sbatch scontrol sinfo; do
    command -v "$b" >/dev/null 2>&1 || die77 "'$b' is not installed (apt-get install slurm-wlm munge)"
  done
  [ "$(id -u)" -eq 0 ] || die77 "not root (slurmd runs each job as its owner, which needs root)"
  dir=$(mktemp -d "${TMPDIR:-/tmp}/rig-slurm.XXXXXXXX")
  chmod 0700 "$dir"
  mkdir -p "$dir/run" "$dir/log" "$dir/state" "$dir/spool" "$dir/munge"
  local host user ctld_port node_port
  host=$(hostname -s)
  user=$(id -un)
  ctld_port=$(free_port)
  node_port=$(free_port)
  while [ "$node_port" = "$ctld_port" ]; do node_port=$(free_port); done

  mungekey --create --keyfile="$dir/munge/munge.key" --bits=1024 >/dev/null 2>&1 ||
    dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
  chmod 0400 "$dir/munge/munge.key"
  if ! munged --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.socket" \
         --pid-file="$dir/run/munged.pid" --log-file="$dir/log/munged.log" \
         --seed-file="$dir/munge/munged.seed" --force 2>"$dir/log/munged.err"; then
    cat "$dir/log/munged.err" "$dir/log/munged.log" >&2 2>/dev/null || true
    down "$dir"; die77 "munged did not start"
  fi

  # Accounting: MariaDB and slurmdbd of this cluster's own, when both are installed.
  local accounting="AccountingStorageType=accounting_storage/none"
  if command -v mariadbd >/dev/null 2>&1 && command -v mariadb-install-db >/dev/null 2>&1 &&
     command -v slurmdbd >/dev/null 2>&1 && command -v sacctmgr >/dev/null 2>&1; then
    local db_port dbd_port db_pass
    db_port=$(free_port)
    dbd_port=$(free_port)
    while [ "$dbd_port" = "$db_port" ] || [ "$dbd_port" = "$ctld_port" ] || [ "$dbd_port" = "$node_port" ]; do
      dbd_port=$(free_port)
    done
    db_pass=$(od -An -N16 -tx1 /dev/urandom | tr -d ' \n')
    mkdir -p "$dir/db"
    if ! mariadb-install-db --no-defaults --user="$user" --datadir="$dir/db" --skip-test-db \
           --auth-root-authentication-method=socket >"$dir/log/mariadb-install.log" 2>&1; then
      cat "$dir/log/mariadb-install.log" >&2
      down "$dir"; die77 "mariadb-install-db failed"
    fi
    mariadbd --no-defaults --user="$user" --datadir="$dir/db" --socket="$dir/run/mariadb.sock" \
      --port="$db_port" --bind-address=127.0.0.1 --pid-file="$dir/run/mariadb.pid" \
      --log-error="$dir/log/mariadb.log" --skip-name-resolve --innodb-buffer-pool-size=32M \
      >/dev/null 2>&1 &
    local i
    for i in $(seq 150); do
      mariadb --no-defaults --socket="$dir/run/mariadb.sock" -e 'SELECT 1' >/dev/null 2>&1 && break
      sleep 0.2
    done
    if ! mariadb --no-defaults --socket="$dir/run/mariadb.sock" -e \
        "CREATE USER 'slurm'@'127.0.0.1' IDENTIFIED BY '${db_pass}'; GRANT ALL ON slurm_acct_db.* TO 'slurm'@'127.0.0.1';" \
        2>"$dir/log/mariadb-user.err"; then
      cat "$dir/log/mariadb-user.err" "$dir/log/mariadb.log" >&2 2>/dev/null || true
      down "$dir"; die77 "MariaDB did not start (or refused its user)"
    fi
    (umask 077; cat >"$dir/slurmdbd.conf" <<EOF
AuthType=auth/munge
AuthInfo=socket=${dir}/munge/munge.socket
DbdHost=localhost
DbdAddr=127.0.0.1
DbdPort=${dbd_port}
SlurmUser=${user}
PidFile=${dir}/run/slurmdbd.pid
LogFile=${dir}/log/slurmdbd.log
DebugLevel=info
StorageType=accounting_storage/mysql
StorageHost=127.0.0.1
StoragePort=${db_port}
StorageUser=slurm
StoragePass=${db_pass}
StorageLoc=slurm_acct_db
EOF
    )
    # slurmdbd reads slurmdbd.conf from the folder of $SLURM_CONF.
    if ! SLURM_CONF="$dir/slurm.conf" slurmdbd 2>"$dir/log/slurmdbd.err"; then
      cat "$dir/log/slurmdbd.err" "$dir/log/slurmdbd.log" >&2 2>/dev/null || true
      down "$dir"; die77 "slurmdbd did not start"
    fi
    accounting="AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=127.0.0.1
AccountingStoragePort=${dbd_port}
AccountingStoragePass=${dir}/munge/munge.socket"
  else
    echo "slurm-local: no accounting (sacct answers nothing): slurmdbd or mariadb-server is not installed" >&2
  fi

  cat >"$dir/slurm.conf" <<EOF
# One-node Slurm on localhost, generated by rig's scripts/slurm-local.sh.
ClusterName=rig-local
SlurmctldHost=${host}(127.0.0.1)
SlurmctldPort=${ctld_port}
SlurmdPort=${node_port}
SlurmUser=${user}
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=${dir}/munge/munge.socket
StateSaveLocation=${dir}/state
SlurmdSpoolDir=${dir}/spool/slurmd-%n
SlurmctldPidFile=${dir}/run/slurmctld.pid
SlurmdPidFile=${dir}/run/slurmd.pid
SlurmctldLogFile=${dir}/log/slurmctld.log
SlurmdLogFile=${dir}/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/linux
JobAcctGatherFrequency=task=1
JobAcctGatherParams=OverMemoryKill
${accounting}
JobCompType=jobcomp/filetxt
JobCompLoc=${dir}/jobcomp.txt
SchedulerType=sched/backfill
# Start queued jobs within a second (defaults suit a big cluster: a pass every 60 s).
SchedulerParameters=sched_interval=1,sched_min_interval=100000,bf_interval=1
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
MpiDefault=none
SwitchType=switch/none
# Finished jobs stay known to scontrol for 10 minutes (Snakemake asks it when sacct cannot answer).
MinJobAge=600
SlurmctldTimeout=30
SlurmdTimeout=30
InactiveLimit=0
KillWait=5
NodeName=${host} NodeAddr=127.0.0.1 CPUs=${cpus} RealMemory=${mem_mb} State=UNKNOWN
PartitionName=debug Nodes=${host} Default=YES MaxTime=INFINITE State=UP
EOF
  # No systemd/cgroup here; an empty cgroup.conf keeps slurmd from probing for one.
  : >"$dir/cgroup.conf"
  export SLURM_CONF="$dir/slurm.conf"

  # The cluster registered in the accounting database before its controller starts.
  if [ -s "$dir/slurmdbd.conf" ]; then
    local j ok=0
    for j in $(seq 50); do
      if sacctmgr -i add cluster rig-local >"$dir/log/sacctmgr.log" 2>&1 ||
         sacctmgr -n -P list cluster format=cluster 2>/dev/null | grep -qx rig-local; then
        ok=1; break
      fi
      sleep 0.2
    done
    if [ "$ok" -ne 1 ]; then
      cat "$dir/log/sacctmgr.log" "$dir/log/slurmdbd.log" >&2 2>/dev/null || true
      down "$dir"; die77 "slurmdbd did not answer sacctmgr"
    fi
  fi

  if ! slurmctld -f "$SLURM_CONF" 2>"$dir/log/slurmctld.err"; then
    cat "$dir/log/slurmctld.err" "$dir/log/slurmctld.log" >&2 2>/dev/null || true
    down "$dir"; die77 "slurmctld did not start"
  fi
  if ! slurmd -f "$SLURM_CONF" -N "$host" 2>"$dir/log/slurmd.err"; then
    cat "$dir/log/slurmd.err" "$dir/log/slurmd.log" >&2 2>/dev/null || true
    down "$dir"; die77 "slurmd did not start"
  fi
  # Up when the node is idle (registered, not down) and a job can be queried.
  local i state=""
  for i in $(seq 150); do
    state=$(sinfo -h -N -n "$host" -o %t 2>/dev/null || true)
    [ "$state" = "idle" ] && break
    sleep 0.2
  done
  if [ "$state" != "idle" ]; then
    tail -n 30 "$dir/log/slurmctld.log" "$dir/log/slurmd.log" >&2 2>/dev/null || true
    down "$dir"; die77 "the node did not come up (state '${state:-none}' after 30 s)"
  fi
}

cmd="${1:-}"
[ $# -gt 0 ] && shift
case "$cmd" in
  run)
    parse_size "$@"
    [ ${#rest[@]} -gt 0 ] || { echo "slurm-local: run: no command given" >&2; exit 2; }
    dir=""
    trap 'down "$dir"' EXIT
    trap 'exit 130' INT
    trap 'exit 143' TERM
    up
    export RIG_SLURM_DIR="$dir"
    # Snakemake's Slurm executor reads $USER (to guess an account); a bare environment lacks it.
    export USER="${USER:-$(id -un)}"
    set +e
    "${rest[@]}"
    status=$?
    set -e
    exit "$status"
    ;;
  up)
    parse_size "$@"
    up
    echo "slurm-local: one-node cluster up in $dir"
    printf 'export SLURM_CONF=%q\n' "$dir/slurm.conf"
    printf '# when done: %q down %q\n' "$0" "$dir"
    ;;
  down)
    [ $# -eq 1 ] && [ -f "$1/slurm.conf" ] || { echo "slurm-local: down DIR (a folder 'up' made)" >&2; exit 2; }
    down "$1"
    ;;
  *)
    sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 2
    ;;
esac
