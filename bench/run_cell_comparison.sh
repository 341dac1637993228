#!/usr/bin/env bash
# millflow's Lees-Edwards media cell (bench_cells, le_media_2000: ~2000 steel balls of 10 mm,
# dense and sheared) against LAMMPS (Debian's `lammps`, one MPI rank, OMP_NUM_THREADS=1) from the
# same state, with the same contact parameters, time step, skin and shear rate, for the same
# number of steps (bench/lammps/in.shear; one pair type, so LAMMPS's single gamma_n is exact).
# The runs alternate, millflow then LAMMPS, REPS times; the fastest of each is kept and the
# ratios millflow / LAMMPS printed per CPU-second and per wall-second (the machine may be shared:
# the CPU figures are the ones to compare then). millflow's figure includes what its cell does
# per step (barostat, LE work, measurement samples); LAMMPS runs a fixed box. Builds nothing:
# build the bench_cells target first.
#
# Usage: bench/run_cell_comparison.sh [BUILD_DIR] [WORK_DIR]   (env: REPS=3, STEPS=2000, LMP=lmp)
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
build=${1:-build}
work=${2:-$(mktemp -d -t millflow-cells-XXXXXX)}
reps=${REPS:-3}
steps=${STEPS:-2000}
lmp=${LMP:-lmp}
scene=le_media_2000
bench_cells=$build/bench/bench_cells
[[ -x $bench_cells ]] || { echo "no $bench_cells: build the bench_cells target first" >&2; exit 1; }
command -v "$lmp" >/dev/null || { echo "no LAMMPS binary '$lmp': apt-get install -y lammps" >&2; exit 1; }
mkdir -p "$work"

echo "load before: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) cores; work dir $work"
best_millflow="" best_lammps=""
for ((r = 0; r < reps; ++r)); do
  # RESULT scene threads particles steps wall-s cpu-s
  "$bench_cells" --benchmark_filter="^$scene/threads:1" --cells_steps="$steps" \
    --cells_cache="$work/cache" --cells_lammps_dir="$work" --benchmark_min_time=0 \
    >"$work/millflow.$r.log" 2>&1
  line=$(awk -v s="$scene" '$1 == "RESULT" && $2 == s && $3 == 1 {print $4, $5, $6, $7}' "$work/millflow.$r.log" | tail -1)
  if [[ -z $best_millflow ]] || awk -v a="$line" -v b="$best_millflow" 'BEGIN {split(a, x); split(b, y); exit !(x[4] < y[4])}'; then
    best_millflow=$line
  fi
  log=$work/lammps.$r.log
  OMP_NUM_THREADS=1 "$lmp" -in "$here/lammps/in.shear" -var dir "$work" -var scene "$scene" \
    -var nsteps "$steps" -log none -screen "$log" -nocite
  # Loop time (wall) and the CPU share LAMMPS reports: CPU seconds = wall x share.
  line=$(awk '/^Loop time of/ {t = $4} /% CPU use/ {c = $1; sub("%", "", c)} END {print t, t * c / 100}' "$log")
  if [[ -z $best_lammps ]] || awk -v a="$line" -v b="$best_lammps" 'BEGIN {split(a, x); split(b, y); exit !(x[2] < y[2])}'; then
    best_lammps=$line
  fi
done
read -r particles done_steps m_wall m_cpu <<<"$best_millflow"
read -r l_wall l_cpu <<<"$best_lammps"
awk -v n="$particles" -v k="$done_steps" -v mw="$m_wall" -v mc="$m_cpu" -v lw="$l_wall" -v lc="$l_cpu" 'BEGIN {
  printf "%-14s %9s %6s | %-24s | %-24s | %s\n", "scene", "particles", "steps", "millflow pts/s (cpu; wall)", "LAMMPS pts/s (cpu; wall)", "millflow / LAMMPS (cpu; wall)"
  printf "%-14s %9d %6d | %10.3gM; %10.3gM | %10.3gM; %10.3gM | %.2f; %.2f\n", "le_media_2000", n, k,
    n * k / mc / 1e6, n * k / mw / 1e6, n * k / lc / 1e6, n * k / lw / 1e6, lc / mc, lw / mw
}'
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
