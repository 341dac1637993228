# What the Slurm tests share (sourced; they set $millflow, $campaign and $here first).
#   require_slurm [MORE_BINARIES]     exits 77 (skipped) unless Slurm's programs are installed
#   start_cluster_and_reference NAME  a scratch directory /tmp/NAME-XXXXXX ($scratch), a private
#                                     single-node cluster in it (private_cluster.sh), and the local
#                                     executor's run of $campaign beside it ($reference, its pid);
#                                     all of it stopped and removed on exit, with $coordinator
#   fail MESSAGE                      prints MESSAGE and the tail of every task log, exits 1
#   query DB SQL                      one value (or rows) of SQL, CSV without its header
#   expect_same_as_local DB LOCAL_DB  every task done, results and artifacts bitwise equal to the
#                                     local executor's run of the same campaign (campaign slurm-small)

require_slurm() {
  local binary
  for binary in sbatch squeue scancel scontrol sinfo slurmctld slurmd munged "$@"; do
    if ! PATH=$PATH:/usr/sbin command -v "$binary" >/dev/null; then
      echo "skipped: $binary is not installed (apt-get install slurm-wlm munge $*)"
      exit 77
    fi
  done
}

cleanup() {
  [ -n "$coordinator" ] && kill -9 "$coordinator" 2>/dev/null || true
  [ -n "$reference" ] && kill -9 "$reference" 2>/dev/null || true
  stop_private_cluster
  rm -rf "$scratch"
}

start_cluster_and_reference() {
  scratch=$(mktemp -d "/tmp/$1-XXXXXX")
  source "$here/private_cluster.sh"
  coordinator=""
  reference=""
  trap cleanup EXIT
  start_private_cluster "$scratch/cluster"
  mkdir -p "$scratch/local" "$scratch/slurm"
  "$millflow" submit "$campaign" --executor local --db "$scratch/local/local.db" --jobs 5 >/dev/null 2>&1 &
  reference=$!
}

fail() {
  echo "FAILED: $*" >&2
  for log in "$scratch"/slurm/*.logs/*.log; do echo "--- $log" >&2; tail -30 "$log" >&2; done
  exit 1
}

query() {
  "$millflow" query --db "$1" --format csv "$2" | tail -n +2
}

expect_same_as_local() {
  local db=$1 local_db=$2
  [ "$(query "$db" "SELECT count(*) FROM tasks WHERE status <> 'done'")" -eq 0 ] || fail "tasks left unfinished"
  "$millflow" export slurm-small --db "$local_db" --format json --out "$scratch/local/export" >/dev/null
  "$millflow" export slurm-small --db "$db" --format json --out "$scratch/slurm/export" >/dev/null
  cmp "$scratch/local/export/slurm-small.json" "$scratch/slurm/export/slurm-small.json" || fail "results differ"
  local artifacts="SELECT task_key, name, sha256, size FROM artifacts ORDER BY task_key, name"
  [ "$(query "$local_db" "$artifacts")" = "$(query "$db" "$artifacts")" ] || fail "artifacts differ"
}
