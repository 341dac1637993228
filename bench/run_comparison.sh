#!/usr/bin/env bash
# Side-by-side DEM throughput of millflow (bench_dem) and LAMMPS on the same scenes: the 1 m mill
# slice (case a, with and without lifters) and the Lees-Edwards shear cells (case c, size ratio 5
# and 10). bench_dem builds each scene, brings it to a flowing state, times it at 1 and 2 threads
# and exports that state; LAMMPS (one MPI rank, OMP_NUM_THREADS=1) then runs the same number of
# steps from the same state with the same parameters (bench/lammps/in.*). Each run is repeated
# REPS times and the fastest kept (the machine may be shared). Builds nothing: build bench_dem
# first (cmake --build BUILD_DIR --target bench_dem).
#
# With BASELINE=OTHER_BUILD_DIR (e.g. a build of an earlier commit), that build's bench_dem runs
# too, right after this one on each scene, and its figures and the ratio new / baseline are
# printed; the warm states both export (written by each build's own steps from the same start)
# are compared byte for byte, which shows whether a change kept the results' bits.
#
# Usage: bench/run_comparison.sh [BUILD_DIR] [WORK_DIR]     (env: REPS=3, LMP=lmp, BASELINE=)
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
build=${1:-build}
work=${2:-$(mktemp -d -t millflow-comparison-XXXXXX)}
reps=${REPS:-3}
lmp=${LMP:-lmp}
bench_dem=$build/bench/bench_dem
[[ -x $bench_dem ]] || { echo "no $bench_dem: build the bench_dem target first" >&2; exit 1; }
command -v "$lmp" >/dev/null || { echo "no LAMMPS binary '$lmp': apt-get install -y lammps" >&2; exit 1; }
baseline=${BASELINE:-}
[[ -z $baseline || -x $baseline/bench/bench_dem ]] || { echo "no $baseline/bench/bench_dem: build it first" >&2; exit 1; }
mkdir -p "$work"
[[ -z $baseline ]] || mkdir -p "$work/baseline"

# scene, LAMMPS input, steps
cases=(
  "mill_1m_bare in.mill 4000"
  "mill_1m in.mill 4000"
  "shear_ratio5 in.shear 300"
  "shear_ratio10 in.shear 60"
)

# Prints "seconds cpu_percent peak_kib" of the fastest of $reps LAMMPS runs.
run_lammps() {
  local input=$1 scene=$2 steps=$3 best="" r
  for ((r = 0; r < reps; ++r)); do
    local log=$work/$scene.lammps.$r.log
    OMP_NUM_THREADS=1 /usr/bin/time -f "PEAK_KIB %M" -o "$log.time" \
      "$lmp" -in "$here/lammps/$input" -var dir "$work" -var scene "$scene" -var nsteps "$steps" \
      -log none -screen "$log" -nocite
    local line
    line=$(awk '/^Loop time of/ {t = $4} /% CPU use/ {c = $1; sub("%", "", c)} END {print t, c}' "$log")
    line="$line $(awk '/PEAK_KIB/ {print $2}' "$log.time")"
    if [[ -z $best ]] || awk -v a="${line%% *}" -v b="${best%% *}" 'BEGIN {exit !(a < b)}'; then best=$line; fi
  done
  echo "$best"
}

echo "load before: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) cores; work dir $work"
printf '\n%-14s %8s %6s | %-33s | %-33s | %s\n' "" "" "" "millflow pts/s/core (wall; cpu)" "LAMMPS 1 core pts/s (wall; cpu)" ""
printf '%-14s %8s %6s | %16s %16s | %16s %16s | %s\n' scene particles steps "1 thread" "2 threads" "1 rank" "peak MiB" "millflow/LAMMPS 1 core (wall; cpu)"
for entry in "${cases[@]}"; do
  read -r scene input steps <<<"$entry"
  "$bench_dem" --benchmark_filter="^$scene/" --benchmark_repetitions="$reps" --dem_steps="$steps" \
    --dem_lammps_dir="$work" >"$work/$scene.millflow.log" 2>&1
  # RESULT scene threads particles steps wall pts/s/core pts/cpu-s peak contacts
  one=$(awk -v s="$scene" '$1 == "RESULT" && $2 == s && $3 == 1' "$work/$scene.millflow.log")
  two=$(awk -v s="$scene" '$1 == "RESULT" && $2 == s && $3 == 2' "$work/$scene.millflow.log")
  particles=$(awk '{print $4}' <<<"$one")
  if [[ -n $baseline ]]; then
    "$baseline/bench/bench_dem" --benchmark_filter="^$scene/" --benchmark_repetitions="$reps" --dem_steps="$steps" \
      --dem_lammps_dir="$work/baseline" >"$work/$scene.baseline.log" 2>&1
    base_one=$(awk -v s="$scene" '$1 == "RESULT" && $2 == s && $3 == 1' "$work/$scene.baseline.log")
    base_two=$(awk -v s="$scene" '$1 == "RESULT" && $2 == s && $3 == 2' "$work/$scene.baseline.log")
    same=differ
    cmp -s "$work/$scene.data" "$work/baseline/$scene.data" && same=identical
    awk -v s="$scene" -v one="$one" -v two="$two" -v b1="$base_one" -v b2="$base_two" -v same="$same" 'BEGIN {
      split(one, a); split(two, b); split(b1, c); split(b2, d)
      printf "%-14s baseline %7.3gM; %5.3gM %7.3gM; %5.3gM | new / baseline 1 thread %.2f; %.2f, 2 threads %.2f; %.2f (wall; cpu) | warm state %s\n",
        s, c[7] / 1e6, c[8] / 1e6, d[7] / 1e6, d[8] / 1e6, a[7] / c[7], a[8] / c[8], b[7] / d[7], b[8] / d[8], same
    }'
  fi
  read -r lmp_s lmp_cpu lmp_kib <<<"$(run_lammps "$input" "$scene" "$steps")"
  awk -v s="$scene" -v n="$particles" -v k="$steps" -v one="$one" -v two="$two" \
      -v ls="$lmp_s" -v lc="$lmp_cpu" -v lk="$lmp_kib" 'BEGIN {
    split(one, a); split(two, b)
    lw = n * k / ls; lcpu = lw / (lc / 100)
    printf "%-14s %8d %6d | %7.3gM; %5.3gM %7.3gM; %5.3gM | %7.3gM; %5.3gM %7.1f/%-7.1f | %.2f; %.2f\n",
      s, n, k, a[7] / 1e6, a[8] / 1e6, b[7] / 1e6, b[8] / 1e6, lw / 1e6, lcpu / 1e6, a[9], lk / 1024,
      a[7] / lw, a[8] / lcpu
  }'
done
echo "(peak MiB: millflow process / LAMMPS process; millflow contacts per particle in $work/*.millflow.log)"
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
