# A private single-node Slurm cluster in a scratch directory (sourced by run_slurm_test.sh).
# Needs root (slurmd runs the jobs; munged's key must belong to the munge user). Ports are private,
# so it runs beside any other Slurm on the machine. No systemd and no slurmdbd: munged gets its own
# socket, slurmctld and slurmd a slurm.conf written below (sacct needs slurmdbd, so state is polled
# with squeue and scontrol).
#   start_private_cluster DIR   starts munged, slurmctld and slurmd; exports SLURM_CONF
#   stop_private_cluster        stops the three daemons by pid

cluster_pids=()

free_port() {
  python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'
}

write_slurm_conf() {
  local dir=$1 name=$2
  local memory_mb
  memory_mb=$(awk '/MemTotal/ { print int($2 / 1024 / 2) }' /proc/meminfo)
  cat > "$dir/slurm.conf" <<EOF
ClusterName=$name
SlurmctldHost=localhost
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$dir/munge/munge.sock
CredType=cred/munge
SlurmctldPort=$(free_port)
SlurmdPort=$(free_port)
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
MinJobAge=3600
KillWait=5
SchedulerParameters=sched_interval=1
ReturnToService=2
NodeName=localhost CPUs=$(nproc) RealMemory=$memory_mb State=UNKNOWN
PartitionName=test Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
}

wait_for() {
  local what=$1 tries=$2
  shift 2
  for _ in $(seq "$tries"); do
    "$@" >/dev/null 2>&1 && return 0
    sleep 0.2
  done
  echo "private cluster: $what did not come up" >&2
  return 1
}

start_private_cluster() {
  local dir=$1
  local name="mf$$"
  mkdir -p "$dir/munge" "$dir/state" "$dir/spool"
  chmod 755 "$(dirname "$dir")" "$dir"  # munged (user munge) must reach its directory
  chown munge:munge "$dir/munge"
  chmod 700 "$dir/munge"
  dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
  chown munge:munge "$dir/munge/munge.key"
  chmod 400 "$dir/munge/munge.key"
  runuser -u munge -- /usr/sbin/munged --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.sock" \
    --pid-file="$dir/munge/munged.pid" --log-file="$dir/munge/munged.log" --seed-file="$dir/munge/seed" --force
  wait_for munged 50 test -S "$dir/munge/munge.sock"
  cluster_pids+=("$(cat "$dir/munge/munged.pid")")

  write_slurm_conf "$dir" "$name"
  export SLURM_CONF=$dir/slurm.conf
  /usr/sbin/slurmctld -f "$SLURM_CONF" -i
  wait_for slurmctld 50 test -s "$dir/slurmctld.pid"
  cluster_pids+=("$(cat "$dir/slurmctld.pid")")
  /usr/sbin/slurmd -f "$SLURM_CONF" -N localhost
  wait_for slurmd 50 test -s "$dir/slurmd.pid"
  cluster_pids+=("$(cat "$dir/slurmd.pid")")
  wait_for "an idle node" 100 bash -c 'sinfo -h -o %t | grep -q idle'
}

stop_private_cluster() {
  local pid
  for pid in "${cluster_pids[@]}"; do
    kill "$pid" 2>/dev/null || true
  done
  for pid in "${cluster_pids[@]}"; do
    for _ in $(seq 50); do
      kill -0 "$pid" 2>/dev/null || break
      sleep 0.1
    done
  done
  cluster_pids=()
}
