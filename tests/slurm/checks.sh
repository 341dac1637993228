# Checks shared by the Slurm tests (sourced after private_cluster.sh; needs $millflow, $scratch).
#   fail MESSAGE                      prints MESSAGE and the tail of every task log, exits 1
#   query DB SQL                      one value (or rows) of SQL, CSV without its header
#   expect_same_as_local DB LOCAL_DB  every task done, results and artifacts bitwise equal to the
#                                     local executor's run of the same campaign (campaign slurm-small)

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
