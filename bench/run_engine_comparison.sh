#!/usr/bin/env bash
# Engine overhead with trivial tasks, millflow against Snakemake, timed with one clock in one run.
#   bench/run_engine_comparison.sh [TASKS] [BUILD_DIR]      (defaults: 1000 build)
# Both run the same DAG: TASKS independent trivial tasks, except that every tenth task depends on
# the previous tenth (the shape of bench/bench_engine.cpp), on 2 concurrent jobs; then the same
# workflow again with everything up to date. millflow runs "sum" test tasks, each committed to its
# SQLite store; Snakemake runs one wildcard rule whose shell step writes one small file (a `run:`
# step would be worse: Snakemake 7 starts a Python process per job for it on --cores 2). Both
# times include process start-up. Needs: apt-get install snakemake.
# SNAKEMAKE_LIMIT_S caps Snakemake's first run (default 0: no cap); when the cap is reached the
# script reports how many outputs Snakemake had written by then instead of the table.
set -euo pipefail

tasks=${1:-1000}
build=${2:-build}
limit_s=${SNAKEMAKE_LIMIT_S:-0}
millflow=$(realpath "$build/millflow_testing")  # the command line with the test kinds
command -v snakemake >/dev/null || { echo "snakemake not found: apt-get install -y snakemake" >&2; exit 2; }
work=$(mktemp -d "${TMPDIR:-/tmp}/millflow-vs-snakemake.XXXXXX")
trap 'rm -rf "$work"' EXIT

python3 - "$tasks" "$work" <<'PY'
import json, sys
tasks, work = int(sys.argv[1]), sys.argv[2]
campaign = []
for i in range(tasks):
    task = {"id": str(i), "kind": "sum", "params": {"value": i}}
    if i >= 10 and i % 10 == 0:
        task["after"] = [str(i - 10)]
    campaign.append(task)
json.dump({"format": "millflow-test", "name": "trivial", "tasks": campaign}, open(f"{work}/trivial.json", "w"))
open(f"{work}/Snakefile", "w").write(f"""
TASKS = {tasks}

def upstream(wildcards):
    i = int(wildcards.i)
    return [f"out/{{i - 10}}.txt"] if i >= 10 and i % 10 == 0 else []

rule all:
    input: expand("out/{{i}}.txt", i=range(TASKS))

rule task:
    input: upstream
    output: "out/{{i}}.txt"
    shell: "echo {{wildcards.i}} > {{output}}"
""")
PY

now() { date +%s.%N; }
declare -A seconds
time_it() {  # name command...; returns 124 when timeout stopped it (its 124, or 137 after its KILL)
  local start end status=0
  start=$(now)
  "${@:2}" >"$work/$1.log" 2>&1 || status=$?
  [ "$status" -ne 124 ] && [ "$status" -ne 137 ] || return 124
  [ "$status" -eq 0 ] || { echo "$1 failed:" >&2; tail -20 "$work/$1.log" >&2; exit 1; }
  end=$(now)
  seconds[$1]=$(python3 -c "print($end - $start)")
}

time_it millflow_run "$millflow" submit "$work/trivial.json" --db "$work/millflow.db" --jobs 2
time_it millflow_cached "$millflow" submit "$work/trivial.json" --db "$work/millflow.db" --jobs 2
grep -q "$tasks cached" "$work/millflow_cached.log" || { echo "millflow resubmission was not fully cached" >&2; exit 1; }
# Snakemake keeps going for minutes after SIGTERM: KILL follows after 30 s.
time_it snakemake_run timeout -k 30 "$limit_s" snakemake --snakefile "$work/Snakefile" --directory "$work/snake" --cores 2 -q || {
  echo "$tasks trivial tasks, 2 jobs: millflow ${seconds[millflow_run]} s, re-run ${seconds[millflow_cached]} s"
  echo "snakemake stopped at the ${limit_s} s cap with $(find "$work/snake/out" -name '*.txt' | wc -l) of $tasks outputs written"
  exit 0
}
time_it snakemake_cached snakemake --snakefile "$work/Snakefile" --directory "$work/snake" --cores 2 -q
[ "$(find "$work/snake/out" -name '*.txt' | wc -l)" -eq "$tasks" ] || { echo "snakemake did not write every output" >&2; exit 1; }

python3 - "$tasks" "${seconds[millflow_run]}" "${seconds[millflow_cached]}" "${seconds[snakemake_run]}" "${seconds[snakemake_cached]}" <<'PY'
import sys
tasks = int(sys.argv[1])
m_run, m_cached, s_run, s_cached = map(float, sys.argv[2:])
print(f"{tasks} trivial tasks, 2 jobs, end to end (process start-up included)")
print(f"{'phase':<28}{'millflow s':>12}{'snakemake s':>13}{'millflow us/task':>18}{'snakemake us/task':>19}{'snakemake/millflow':>20}")
for phase, m, s in (("first run", m_run, s_run), ("re-run, all up to date", m_cached, s_cached)):
    print(f"{phase:<28}{m:>12.3f}{s:>13.3f}{m / tasks * 1e6:>18.0f}{s / tasks * 1e6:>19.0f}{s / m:>20.1f}")
PY
