#!/usr/bin/env bash
# millflow's dense shear cells (bench_cells) against LAMMPS (Debian's `lammps`, one MPI rank,
# OMP_NUM_THREADS=1) from the same state, with the same contact parameters, time step, skin and
# shear rate, for the same number of steps:
#   le_media_2000   ~2000 steel balls of 10 mm (bench/lammps/in.shear: gran/hooke/history, one
#                   pair type, so its single gamma_n is exact)
#   cement_load05   a media + powder mixture: 50 mm balls and clinker powder of 0.125 d, 38k
#                   particles (bench/lammps/in.cell_mixture: pair granular, coefficients per pair
#                   of types, exact damping)
# The runs alternate, millflow then LAMMPS, scene by scene, REPS times; the fastest of each is
# kept and the ratios millflow / LAMMPS printed per CPU-second and per wall-second (the machine
# may be shared: the CPU figures are the ones to compare then). millflow's figure includes what
# its cell does per step (barostat, LE work, measurement samples); LAMMPS runs a fixed box.
# Builds nothing: build the bench_cells target first. Preparing a cement cell takes minutes:
# point CELLS_CACHE at a bench_cells --cells_cache folder that holds it.
#
# Usage: bench/run_cell_comparison.sh [BUILD_DIR] [WORK_DIR]
#   env: REPS=3, SCENES="le_media_2000 cement_load05", STEPS=2000 (media cell),
#        MIX_STEPS=100 (mixture), CELLS_CACHE=WORK_DIR/cache, LMP=lmp,
#        WARMUP_STRAIN (passed as --cells_warmup_strain, to time a state prepared with a
#        shorter warm-up than bench_cells' default; unset: the default),
#        STIFFNESS (passed as --cells_stiffness: policy times the cells at the contacts a
#        campaign's cell runs, and LAMMPS gets those; unset: the campaign file's)
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
build=${1:-build}
work=${2:-$(mktemp -d -t millflow-cells-XXXXXX)}
reps=${REPS:-3}
scenes=${SCENES:-le_media_2000 cement_load05}
lmp=${LMP:-lmp}
cache=${CELLS_CACHE:-$work/cache}
cell_flags=()
[[ -n ${WARMUP_STRAIN:-} ]] && cell_flags=(--cells_warmup_strain="$WARMUP_STRAIN")
[[ -n ${STIFFNESS:-} ]] && cell_flags+=(--cells_stiffness="$STIFFNESS")
bench_cells=$build/bench/bench_cells
[[ -x $bench_cells ]] || { echo "no $bench_cells: build the bench_cells target first" >&2; exit 1; }
command -v "$lmp" >/dev/null || { echo "no LAMMPS binary '$lmp': apt-get install -y lammps" >&2; exit 1; }
mkdir -p "$work"

input_of() { [[ $1 == le_media_2000 ]] && echo "$here/lammps/in.shear" || echo "$here/lammps/in.cell_mixture"; }
steps_of() { [[ $1 == le_media_2000 ]] && echo "${STEPS:-2000}" || echo "${MIX_STEPS:-100}"; }
# Keeps, per key, the line whose field `field` is smallest.
declare -A best
keep_fastest() {
  local key=$1 field=$2 line=$3
  if [[ -z ${best[$key]:-} ]] || awk -v a="$line" -v b="${best[$key]}" -v f="$field" \
    'BEGIN {split(a, x); split(b, y); exit !(x[f] < y[f])}'; then
    best[$key]=$line
  fi
}

echo "load before: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) cores; work dir $work"
for ((r = 0; r < reps; ++r)); do
  for scene in $scenes; do
    steps=$(steps_of "$scene")
    # RESULT scene threads particles steps wall-s cpu-s state HASH
    "$bench_cells" --benchmark_filter="^$scene/threads:1" --cells_steps="$steps" \
      --cells_cache="$cache" --cells_lammps_dir="$work" --benchmark_min_time=0 "${cell_flags[@]}" \
      >"$work/millflow.$scene.$r.log" 2>&1
    keep_fastest "m_$scene" 4 "$(awk -v s="$scene" '$1 == "RESULT" && $2 == s && $3 == 1 {print $4, $5, $6, $7}' "$work/millflow.$scene.$r.log" | tail -1)"
    log=$work/lammps.$scene.$r.log
    OMP_NUM_THREADS=1 "$lmp" -in "$(input_of "$scene")" -var dir "$work" -var scene "$scene" -var lammps "$here/lammps" \
      -var nsteps "$steps" -log none -screen "$log" -nocite
    # Loop time (wall) and the CPU share LAMMPS reports: CPU seconds = wall x share.
    keep_fastest "l_$scene" 2 "$(awk '/^Loop time of/ {t = $4} /% CPU use/ {c = $1; sub("%", "", c)} END {print t, t * c / 100}' "$log")"
  done
done
printf "%-14s %9s %6s | %-24s | %-24s | %s\n" scene particles steps "millflow pts/s (cpu; wall)" \
  "LAMMPS pts/s (cpu; wall)" "millflow / LAMMPS (cpu; wall)"
for scene in $scenes; do
  read -r particles done_steps m_wall m_cpu <<<"${best[m_$scene]}"
  read -r l_wall l_cpu <<<"${best[l_$scene]}"
  awk -v s="$scene" -v n="$particles" -v k="$done_steps" -v mw="$m_wall" -v mc="$m_cpu" \
    -v lw="$l_wall" -v lc="$l_cpu" 'BEGIN {
    printf "%-14s %9d %6d | %10.3gM; %10.3gM | %10.3gM; %10.3gM | %.2f; %.2f\n", s, n, k,
      n * k / mc / 1e6, n * k / mw / 1e6, n * k / lc / 1e6, n * k / lw / 1e6, lc / mc, lw / mw
  }'
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
