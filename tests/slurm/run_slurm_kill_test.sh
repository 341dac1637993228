#!/usr/bin/env bash
# The Slurm coordinator killed at random moments: `millflow submit --executor slurm` on a private
# single-node cluster (private_cluster.sh) gets SIGKILL after a random 0.02-1.5 s, then each
# `millflow resume` after it, KILLS times (default 12; the moments come from RANDOM seeded with
# SEED, default 1), so kills land wherever the coordinator is: submitting arrays, recording their
# ids, polling, ingesting what finished while none watched; a last resume runs to the end.
# Checks: every task done, Slurm saw exactly one job per task (nothing submitted twice, nothing
# lost), each task one attempt, and results and artifacts bitwise equal to a run of the same
# campaign with the local executor. (run_slurm_test.sh kills at chosen moments and checks the
# checkpoint signal; this one kills anywhere.)
# Usage: run_slurm_kill_test.sh MILLFLOW_BINARY CAMPAIGN_FILE. Exit 77 (skipped) without Slurm.
set -euo pipefail
millflow=$(realpath "$1")
campaign=$(realpath "$2")
here=$(dirname "$(realpath "$0")")
source "$here/common.sh"
require_slurm
kills=${KILLS:-12}

start_cluster_and_reference millflow-slurm-kill
db=$scratch/slurm/slurm.db

command=(submit "$campaign" --executor slurm --db "$db" --poll-interval 0.3)
moments=()
RANDOM=${SEED:-1}
for _ in $(seq "$kills"); do
  "$millflow" "${command[@]}" >>"$scratch/coordinator.out" 2>>"$scratch/coordinator.err" &
  coordinator=$!
  draw=$RANDOM  # here: a subshell's $RANDOM is seeded afresh
  delay=$(awk -v r="$draw" 'BEGIN {printf "%.2f", 0.02 + 1.5 * r / 32767}')
  sleep "$delay"
  if kill -9 "$coordinator" 2>/dev/null; then
    moments+=("$delay")
  else
    moments+=("ended")  # the campaign was already done
  fi
  wait "$coordinator" 2>/dev/null || true
  coordinator=""
  # Resume once the database holds the campaign (a kill within its first milliseconds may not).
  if [ "$(query "$db" "SELECT count(*) FROM campaigns" 2>/dev/null || echo 0)" -ge 1 ]; then
    command=(resume --db "$db" --poll-interval 0.3)
  fi
done
echo "coordinator killed after (s): ${moments[*]}"
"$millflow" resume --db "$db" --poll-interval 0.3 >>"$scratch/coordinator.out" 2>>"$scratch/coordinator.err" ||
  fail "the last resume exited $?: $(tail -5 "$scratch/coordinator.err")"

wait "$reference" || fail "the local reference run failed"
reference=""
task_count=$(query "$scratch/local/local.db" "SELECT count(*) FROM tasks")
[ "$(query "$db" "SELECT count(*) FROM jobs")" -eq "$task_count" ] || fail "jobs recorded != $task_count tasks"
[ "$(query "$db" "SELECT max(attempt) FROM jobs")" -eq 1 ] || fail "a task was submitted twice"
slurm_elements=$(squeue --noheader --array --states=all --format=%i | wc -l)
[ "$slurm_elements" -eq "$task_count" ] || fail "Slurm ran $slurm_elements jobs for $task_count tasks"
expect_same_as_local "$db" "$scratch/local/local.db"
echo "slurm kill test passed: $kills kills, $task_count tasks, $slurm_elements Slurm jobs"
