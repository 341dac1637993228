#!/usr/bin/env bash
# The Slurm executor against a real Slurm: a private single-node cluster (private_cluster.sh) runs
# tests/slurm/campaign.json through `millflow submit --executor slurm`; the coordinator is killed
# (SIGKILL) while jobs are queued or running, and the ids of its first array are erased from the
# store as if it had died between sbatch and recording them. `millflow resume` then re-attaches:
# to most jobs by id, to that array's by its job name. While resume runs, the checkpointing task
# (kind steps) gets USR1 as a time limit's --signal would send it (scancel --signal=USR1 --batch):
# it must exit 75, be submitted again and continue from its checkpoint. Checks: Slurm saw one job
# per task plus that resubmission (nothing submitted twice), and results and artifacts are
# bitwise equal to a run of the same campaign with the local executor.
# Usage: run_slurm_test.sh MILLFLOW_BINARY CAMPAIGN_FILE. Exit 77 (skipped) without Slurm.
set -euo pipefail
millflow=$(realpath "$1")
campaign=$(realpath "$2")
here=$(dirname "$(realpath "$0")")
source "$here/common.sh"
require_slurm sqlite3

started=$(date +%s.%N)
# The cluster, and the reference beside it: the same campaign with the local executor (its tasks
# mostly sleep).
start_cluster_and_reference millflow-slurm
echo "cluster up after $(echo "$(date +%s.%N) - $started" | bc) s"
db=$scratch/slurm/slurm.db

# Submit through Slurm and kill the coordinator once its first jobs are queued or running.
"$millflow" submit "$campaign" --executor slurm --db "$db" --poll-interval 0.3 >/dev/null 2>"$scratch/submit.err" &
coordinator=$!
for _ in $(seq 200); do
  [ -f "$db" ] && [ "$(query "$db" "SELECT count(*) FROM jobs WHERE job_id <> ''" 2>/dev/null || echo 0)" -ge 4 ] && break
  sleep 0.1
done
kill -9 "$coordinator"
wait "$coordinator" 2>/dev/null || true
coordinator=""
in_flight=$(query "$db" "SELECT count(*) FROM tasks WHERE status = 'running'")
[ "$in_flight" -ge 1 ] || fail "no task was running when the coordinator was killed"
echo "coordinator killed with $in_flight task(s) submitted and unfinished"
# As if it had died just after sbatch: the first array's jobs recorded, their ids not.
first_array=$(query "$db" "SELECT job_name FROM jobs ORDER BY submitted_at, job_id LIMIT 1")
sqlite3 "$db" "UPDATE jobs SET job_id = '', state = 'SUBMITTING' WHERE job_name = '$first_array'"
sleep 3  # some jobs finish while no coordinator runs: resume ingests them

"$millflow" resume --db "$db" --poll-interval 0.3 >"$scratch/resume.out" 2>"$scratch/resume.err" &
coordinator=$!

# A checkpoint signal for the steps task once it has checkpointed a few steps.
long_key=$(query "$db" "SELECT key FROM tasks WHERE kind = 'steps'")
checkpoint=$db.jobs/work/$long_key/steps.checkpoint
long_job=""
for _ in $(seq 300); do
  long_job=$(query "$db" "SELECT job_id FROM jobs WHERE task_key = '$long_key' AND attempt = 1" 2>/dev/null || true)
  if [ -n "$long_job" ] && [ -f "$checkpoint" ] && [ "$(cut -d' ' -f1 "$checkpoint")" -ge 3 ]; then break; fi
  long_job=""
  sleep 0.1
done
[ -n "$long_job" ] || fail "the steps task's job never checkpointed 3 steps"
# scancel retries while the job is "in a transitional state" and then fails with "already
# completing" when the job exited on the first signal: its exit code proves nothing, the checks
# below do.
scancel --signal=USR1 --batch "$long_job" 2>/dev/null || true
echo "sent USR1 to job $long_job at checkpoint step $(cut -d' ' -f1 "$checkpoint")"

wait "$coordinator" || fail "resume exited $?: $(cat "$scratch/resume.err")"
coordinator=""
cat "$scratch/resume.out"

wait "$reference" || fail "the local reference run failed"
reference=""
task_count=$(query "$scratch/local/local.db" "SELECT count(*) FROM tasks")
grep -q "re-attached to job" "$scratch"/slurm/slurm.db.logs/*.log || fail "resume did not re-attach to any job"
[ "$(query "$db" "SELECT count(*) FROM jobs WHERE job_name = '$first_array' AND job_id = ''")" -eq 0 ] ||
  fail "resume did not find the jobs of $first_array by name"

# The signalled job stopped at a checkpoint (exit 75); its next attempt continued from that step.
scontrol show job "$long_job" | grep -q "ExitCode=75:0" || fail "job $long_job did not exit 75: $(scontrol show job "$long_job")"
[ "$(query "$db" "SELECT group_concat(state, ' ') FROM (SELECT state FROM jobs WHERE task_key = '$long_key' ORDER BY attempt)")" = \
  "STOPPED COMPLETED" ] || fail "the checkpointed task's jobs are not STOPPED then COMPLETED"
stopped_at=$(sed -n 's/^stopped at step \([0-9]*\) of 40$/\1/p' "$(query "$db" "SELECT stderr_path FROM jobs WHERE task_key = '$long_key' AND attempt = 1")")
continued_at=$(sed -n 's/^continuing from step \([0-9]*\) of 40$/\1/p' "$(query "$db" "SELECT stderr_path FROM jobs WHERE task_key = '$long_key' AND attempt = 2")")
[ -n "$stopped_at" ] && [ "$stopped_at" -ge 3 ] && [ "$continued_at" = "$stopped_at" ] ||
  fail "the second attempt did not continue from the checkpoint (stopped at '$stopped_at', continued at '$continued_at')"
echo "the steps task stopped at step $stopped_at, exit 75, and its second attempt continued from step $continued_at"

# Nothing submitted twice: one job per task, plus the checkpointed task's second attempt.
[ "$(query "$db" "SELECT count(*) FROM jobs")" -eq $((task_count + 1)) ] || fail "jobs recorded != $task_count tasks + 1"
[ "$(query "$db" "SELECT max(attempt) FROM jobs WHERE task_key <> '$long_key'")" -eq 1 ] || fail "a task was submitted twice"
slurm_elements=$(squeue --noheader --array --states=all --format=%i | wc -l)
[ "$slurm_elements" -eq $((task_count + 1)) ] || fail "Slurm ran $slurm_elements jobs for $task_count tasks + 1"

# Every task done, bitwise equal results and artifacts.
expect_same_as_local "$db" "$scratch/local/local.db"

echo "slurm test passed: $task_count tasks, $slurm_elements Slurm jobs, in $(echo "$(date +%s.%N) - $started" | bc) s"
