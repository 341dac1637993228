#!/usr/bin/env bash
# The Slurm executor against a real Slurm: a private single-node cluster (private_cluster.sh) runs
# tests/slurm/campaign.json through `millflow submit --executor slurm`; the coordinator is killed
# (SIGKILL) while jobs are queued or running and `millflow resume` re-attaches to them. Checks:
# Slurm saw exactly one job per task (nothing submitted twice), resume re-attached, and results
# and artifacts are bitwise equal to a run of the same campaign with the local executor.
# Usage: run_slurm_test.sh MILLFLOW_BINARY CAMPAIGN_FILE. Exit 77 (skipped) without Slurm.
set -euo pipefail
for binary in sbatch squeue sinfo slurmctld slurmd munged; do
  if ! PATH=$PATH:/usr/sbin command -v "$binary" >/dev/null; then
    echo "skipped: $binary is not installed (apt-get install slurm-wlm munge)"
    exit 77
  fi
done
millflow=$(realpath "$1")
campaign=$(realpath "$2")
here=$(dirname "$(realpath "$0")")

started=$(date +%s.%N)
scratch=$(mktemp -d /tmp/millflow-slurm-XXXXXX)
source "$here/private_cluster.sh"
coordinator=""
cleanup() {
  [ -n "$coordinator" ] && kill -9 "$coordinator" 2>/dev/null || true
  stop_private_cluster
  rm -rf "$scratch"
}
trap cleanup EXIT

fail() {
  echo "FAILED: $*" >&2
  for log in "$scratch"/slurm/*.logs/*.log; do echo "--- $log" >&2; tail -30 "$log" >&2; done
  exit 1
}
query() {  # query DB SQL: one value
  "$millflow" query --db "$1" --format csv "$2" | tail -n +2
}

start_private_cluster "$scratch/cluster"
echo "cluster up after $(echo "$(date +%s.%N) - $started" | bc) s"

# The reference: the same campaign with the local executor.
mkdir -p "$scratch/local" "$scratch/slurm"
"$millflow" submit "$campaign" --executor local --db "$scratch/local/local.db" --jobs 4 2>/dev/null
db=$scratch/slurm/slurm.db
task_count=$(query "$scratch/local/local.db" "SELECT count(*) FROM tasks")

# Submit through Slurm and kill the coordinator once its first jobs are queued or running.
"$millflow" submit "$campaign" --executor slurm --db "$db" --poll-interval 0.3 >/dev/null 2>"$scratch/submit.err" &
coordinator=$!
for _ in $(seq 200); do
  [ -f "$db" ] && [ "$(query "$db" "SELECT count(*) FROM jobs" 2>/dev/null || echo 0)" -ge 4 ] && break
  sleep 0.1
done
kill -9 "$coordinator"
wait "$coordinator" 2>/dev/null || true
coordinator=""
in_flight=$(query "$db" "SELECT count(*) FROM tasks WHERE status = 'running'")
[ "$in_flight" -ge 1 ] || fail "no task was running when the coordinator was killed"
echo "coordinator killed with $in_flight task(s) submitted and unfinished"
sleep 3  # some jobs finish while no coordinator runs: resume ingests them

"$millflow" resume --db "$db" --poll-interval 0.3 >"$scratch/resume.out" 2>"$scratch/resume.err" ||
  fail "resume exited $?: $(cat "$scratch/resume.err")"
cat "$scratch/resume.out"

grep -q "re-attached to job" "$scratch"/slurm/slurm.db.logs/*.log || fail "resume did not re-attach to any job"
[ "$(query "$db" "SELECT count(*) FROM jobs")" -eq "$task_count" ] || fail "jobs recorded != $task_count tasks"
[ "$(query "$db" "SELECT max(attempt) FROM jobs")" -eq 1 ] || fail "a task was submitted twice"
slurm_elements=$(squeue --noheader --array --states=all --format=%i | wc -l)
[ "$slurm_elements" -eq "$task_count" ] || fail "Slurm ran $slurm_elements jobs for $task_count tasks"

# Bitwise equal results and artifacts.
"$millflow" export slurm-small --db "$scratch/local/local.db" --format json --out "$scratch/local/export" >/dev/null
"$millflow" export slurm-small --db "$db" --format json --out "$scratch/slurm/export" >/dev/null
cmp "$scratch/local/export/slurm-small.json" "$scratch/slurm/export/slurm-small.json" || fail "results differ"
artifacts="SELECT task_key, name, sha256, size FROM artifacts ORDER BY task_key, name"
[ "$(query "$scratch/local/local.db" "$artifacts")" = "$(query "$db" "$artifacts")" ] || fail "artifacts differ"
[ "$(query "$db" "SELECT count(*) FROM tasks WHERE status <> 'done'")" -eq 0 ] || fail "tasks left unfinished"

echo "slurm test passed: $task_count tasks, $slurm_elements Slurm jobs, in $(echo "$(date +%s.%N) - $started" | bc) s"
