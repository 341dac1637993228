#!/usr/bin/env bash
# millflow's media-only Lees-Edwards cell against LAMMPS on the same cell (issue 12: friction
# within 3%): bench_cell_physics --tables 6 builds the campaign's media cell (50 mm steel balls,
# cement_ball_mill.json's contact parameters, stiffness policy), brings it to a stationary state
# under its barostat at inertial number INERTIAL and 20 kPa, writes that state and the contact
# parameters for bench/lammps/in.cell_physics, and shears it on at FIXED volume for STRAIN,
# writing its stress tensor every 50 steps. LAMMPS (Debian's `lmp`, one rank, gran/hooke/history,
# fix deform xy erate ... remap v) shears the same state for the same steps. Both stress series
# are then reduced by the same code below: the first DISCARD strain left out, the rest cut into
# BATCHES batches, each batch's tau = -p_xy, p_yy and p = trace / 3 averaged, the frictions
# tau / p_yy and tau / p formed per batch; mean and standard error over the batches. At fixed
# volume the solid fraction is the same by construction (printed), so the stresses are compared.
# Builds nothing: build the bench_cell_physics target first. docs/cell_validation.md has a run.
#
# Usage: bench/run_cell_physics_comparison.sh [BUILD_DIR] [WORK_DIR]
#        env: SIZE="8 8 8" INERTIAL=0.1 STRAIN=10 DISCARD=1 BATCHES=10 LMP=lmp
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
build=${1:-build}
work=${2:-$(mktemp -d -t millflow-cell-physics-XXXXXX)}
size=${SIZE:-8 8 8}
inertial=${INERTIAL:-0.1}
strain=${STRAIN:-10}
discard=${DISCARD:-1}
batches=${BATCHES:-10}
lmp=${LMP:-lmp}
bench=$build/bench/bench_cell_physics
[[ -x $bench ]] || { echo "no $bench: build the bench_cell_physics target first" >&2; exit 1; }
command -v "$lmp" >/dev/null || { echo "no LAMMPS binary '$lmp': apt-get install -y lammps" >&2; exit 1; }
mkdir -p "$work"

echo "load before: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) cores; work dir $work"
# shellcheck disable=SC2086  # SIZE is three numbers
"$bench" --tables 6 --size $size --lammps_dir "$work" --lammps_inertial_number "$inertial" \
  --lammps_strain "$strain" | tee "$work/millflow.log"
start=$(awk '{print $16 + $17}' /proc/$$/stat)
OMP_NUM_THREADS=1 "$lmp" -in "$here/lammps/in.cell_physics" -var dir "$work" \
  -log "$work/lammps.log" -screen none -nocite
lammps_cpu=$(awk -v s="$start" -v hz="$(getconf CLK_TCK)" '{print ($16 + $17 - s) / hz}' /proc/$$/stat)
echo "LAMMPS: $lammps_cpu CPU s ($(awk '/^Loop time of/ {print $4, "s loop wall"}' "$work/lammps.log"))"

param() { awk -v n="$1" '$1 == "variable" && $2 == n {print $4}' "$work/cell_physics.params"; }
dt=$(param dt)
rate=$(param shear_rate)
echo "solid fraction (both, fixed volume): $(param solid_fraction)"

# Mean and batch standard error of tau, p_yy, p, tau / p_yy, tau / p of one stress series
# (columns: step pxx pyy pzz pxy pxz pyz).
reduce() {
  awk -v dt="$dt" -v rate="$rate" -v discard="$discard" -v nb="$batches" -v name="$2" '
    /^#/ {next}
    NF >= 7 && $1 * dt * rate > discard {n++; xx[n] = $2; yy[n] = $3; zz[n] = $4; xy[n] = $5}
    END {
      per = int(n / nb)
      for (b = 0; b < nb; b++) {
        t = 0; y = 0; p = 0
        for (i = b * per + 1; i <= (b + 1) * per; i++) {t -= xy[i]; y += yy[i]; p += (xx[i] + yy[i] + zz[i]) / 3}
        v[1, b] = t / per; v[2, b] = y / per; v[3, b] = p / per
        v[4, b] = t / y; v[5, b] = t / p
      }
      printf "%s", name
      for (q = 1; q <= 5; q++) {
        m = 0; for (b = 0; b < nb; b++) m += v[q, b]; m /= nb
        s = 0; for (b = 0; b < nb; b++) s += (v[q, b] - m) ^ 2
        printf " %.6g %.6g", m, sqrt(s / (nb - 1) / nb)
      }
      printf " %d\n", n
    }' "$1"
}
m=$(reduce "$work/millflow_stress.txt" millflow)
l=$(reduce "$work/lammps_stress.txt" LAMMPS)
awk -v m="$m" -v l="$l" -v discard="$discard" -v nb="$batches" 'BEGIN {
  split(m, a); split(l, b)
  split("tau_Pa p_yy_Pa p_Pa tau/p_yy tau/p", names)
  printf "after %g strain, %d batches (%d and %d samples)\n", discard, nb, a[12], b[12]
  printf "%-10s %24s %24s %8s %8s\n", "quantity", "millflow", "LAMMPS", "diff %", "diff/se"
  pass = 1
  for (q = 1; q <= 5; q++) {
    mm = a[2 * q]; ms = a[2 * q + 1]; lm = b[2 * q]; ls = b[2 * q + 1]
    d = 100 * (mm - lm) / lm
    printf "%-10s %12.6g +- %-9.3g %12.6g +- %-9.3g %+8.2f %+8.1f\n", names[q], mm, ms, lm, ls, d, (mm - lm) / sqrt(ms ^ 2 + ls ^ 2)
    if (q >= 4 && (d > 3 || d < -3)) pass = 0
  }
  print (pass ? "friction within 3%: PASS" : "friction within 3%: FAIL")
}'
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
