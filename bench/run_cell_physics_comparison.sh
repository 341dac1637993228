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
# STRESS_CONTROL=1: both codes shear on holding the normal stress instead (millflow under its
# cell's barostat, LAMMPS under its Nose-Hoover barostat on y, or with LAMMPS_BAROSTAT=stretch
# under millflow's barostat law: bench/lammps/stretch_barostat.lmp), and the solid fraction is
# compared as well (within 0.01).
#
# With LOAD > 0 the cell holds powder of POWDER_RATIO ball diameters at that load (type 2; the
# contact parameters per pair of types, LAMMPS's pair_style granular through
# bench/lammps/in.cell_physics_mixture). First, per pair of types, a head-on collision in LAMMPS
# (in.restitution_pair) against the restitution millflow's material table gives the pair, at the
# cell's dt and at a tenth of it, and two oblique collisions (1 m/s along the line of centres, 1
# and 5 m/s across it: sticking, then sliding throughout), whose rebounds millflow's log prints
# for the same pairs at the cell's dt. Then as above, and from contacts sampled every CONTACT_EVERY
# steps in both codes (millflow's own, LAMMPS's compute pair/local rows reduced below) each pair
# type's share of tau and of p (its contact stress over all contacts'), its contacts per particle
# (2 x contacts / all particles) and its mean overlap / smaller diameter, batch-reduced by the
# same code; the shares pass within 2 combined standard errors.
# Builds nothing: build the bench_cell_physics target first. docs/cell_validation.md has runs.
#
# Usage: bench/run_cell_physics_comparison.sh [BUILD_DIR] [WORK_DIR]
#        env: SIZE="8 8 8" INERTIAL=0.1 STRAIN=10 DISCARD=1 BATCHES=10 LMP=lmp
#             LOAD=0 (media only) POWDER_RATIO=0.5 CONTACT_EVERY=500 SEED=1 (the cell's /dem/seed)
#             OVERLAP=1: millflow's fixed-volume run beside LAMMPS's (two cores; the same results)
#             REDUCE_ONLY=1: only the reduction, of the files an earlier run left in WORK_DIR
#             DT_REFINE=1: millflow's run at the cell's dt / DT_REFINE (an integer; LAMMPS's
#                stays at the cell's dt), the integrator's share of a difference
#             STRESS_CONTROL=1: at the held normal stress, not the volume (above)
#             LAMMPS_BAROSTAT=nph: LAMMPS's barostat under stress control, nph (Nose-Hoover) or
#                stretch (millflow's law in a loop of runs: a third reference, LAMMPS's contacts
#                under millflow's box)
#             SAMPLE_EVERY=50: steps between stress samples (under stress control the bench takes the
#                first interval from it prime to the barostat's, 40 steps at the default steps per
#                collision, so that the samples fall on every phase of it: docs/cell_validation.md,
#                "LAMMPS under stress control"; 51 for 50)
#             PAIRS_ONLY=1 (with LOAD > 0): only the pair collisions, of the cell as placed, in both
#                codes at the cell's dt and a tenth of it (seconds)
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
load=${LOAD:-0}
powder_ratio=${POWDER_RATIO:-0.5}
contact_every=${CONTACT_EVERY:-500}
overlap=${OVERLAP:-0}
seed=${SEED:-1}
reduce_only=${REDUCE_ONLY:-0}
pairs_only=${PAIRS_ONLY:-0}
dt_refine=${DT_REFINE:-1}
stress_control=${STRESS_CONTROL:-0}
lammps_barostat=${LAMMPS_BAROSTAT:-nph}
[[ $lammps_barostat == nph || $lammps_barostat == stretch ]] ||
  { echo "LAMMPS_BAROSTAT=$lammps_barostat: use nph or stretch" >&2; exit 1; }
sample_every=${SAMPLE_EVERY:-50}
with_powder=$(awk -v l="$load" 'BEGIN {print (l > 0) ? 1 : 0}')
bench=$build/bench/bench_cell_physics
[[ -x $bench ]] || { echo "no $bench: build the bench_cell_physics target first" >&2; exit 1; }
command -v "$lmp" >/dev/null || { echo "no LAMMPS binary '$lmp': apt-get install -y lammps" >&2; exit 1; }
mkdir -p "$work"

# LAMMPS's pair collisions on the .params file in WORK_DIR: head-on and oblique (bench_cell_physics's
# kObliqueSpeeds), at the cell's dt and at a tenth of it (what is left there is the integrator's).
pair_collisions() {
  for refine in 1 10; do
    for vt in 0 1 5; do
      for types in "1 1" "1 2" "2 2"; do
        read -r ta tb <<<"$types"
        "$lmp" -in "$here/lammps/in.restitution_pair" -var dir "$work" -var lammps "$here/lammps" \
          -var ta "$ta" -var tb "$tb" -var refine "$refine" -var vt "$vt" \
          -var out "$work/restitution.txt" -log none -screen none -nocite
        cat "$work/restitution.txt"
      done
    done
  done
}

if ((pairs_only)); then
  ((with_powder)) || { echo "PAIRS_ONLY=1 needs LOAD > 0" >&2; exit 1; }
  # millflow's at the cell's dt and a tenth of it, as LAMMPS's below.
  for refine in 1 10; do
    # shellcheck disable=SC2086  # SIZE is three numbers
    "$bench" --tables 6 --size $size --lammps_dir "$work" --lammps_load "$load" \
      --powder_ratio "$powder_ratio" --seed "$seed" --lammps_pairs_only \
      --lammps_pair_refine "$refine" | grep -E 'restitution|oblique'
  done
  pair_collisions
  exit 0
fi

# Both codes on one cell (REDUCE_ONLY=1 skips this and reduces what WORK_DIR holds).
run_both() {
  echo "load before: $(cut -d' ' -f1-3 /proc/loadavg); $(nproc) cores; work dir $work"
  powder_args=()
  input=$here/lammps/in.cell_physics
  if ((with_powder)); then
    powder_args=(--lammps_load "$load" --powder_ratio "$powder_ratio"
                 --lammps_contact_every "$contact_every")
    input=$here/lammps/in.cell_physics_mixture
  fi
  # shellcheck disable=SC2086  # SIZE is three numbers
  bench_args=(--tables 6 --size $size --lammps_dir "$work" --lammps_inertial_number "$inertial"
              --lammps_strain "$strain" --seed "$seed" --lammps_dt_refine "$dt_refine"
              --lammps_sample_every "$sample_every" "${powder_args[@]}")
  ((stress_control)) && bench_args+=(--lammps_stress_control)
  if ((overlap)); then
    # millflow's fixed-volume run beside LAMMPS's: LAMMPS starts once the state is written (the bench
    # opens millflow_stress.txt after it), millflow's log comes when it ends.
    rm -f "$work/millflow_stress.txt"
    "$bench" "${bench_args[@]}" >"$work/millflow.log" &
    bench_pid=$!
    until [[ -e $work/millflow_stress.txt ]]; do
      kill -0 "$bench_pid" 2>/dev/null || { cat "$work/millflow.log"; wait "$bench_pid"; exit 1; }
      sleep 2
    done
  else
    "$bench" "${bench_args[@]}" | tee "$work/millflow.log"
  fi
  if ((with_powder)); then pair_collisions; fi
  # LAMMPS's CPU time: its subshell's children's (the bench, a child of this shell, is not one).
  lammps_cpu=$(
    OMP_NUM_THREADS=1 "$lmp" -in "$input" -var dir "$work" -var lammps "$here/lammps" \
      -var barostat "$lammps_barostat" -log "$work/lammps.log" -screen none -nocite
    awk -v hz="$(getconf CLK_TCK)" '{print ($16 + $17) / hz}' "/proc/$BASHPID/stat"
  )
  echo "LAMMPS: $lammps_cpu CPU s ($(awk '/^Loop time of/ {wall += $4} END {print wall, "s loop wall"}' "$work/lammps.log"))"
  if ((overlap)); then
    wait "$bench_pid"
    cat "$work/millflow.log"
  fi
}
((reduce_only)) || run_both

param() { awk -v n="$1" '$1 == "variable" && $2 == n {print $4}' "$work/cell_physics.params"; }
dt=$(param dt)
rate=$(param shear_rate)
if ((stress_control)); then
  echo "solid fraction (both, at the start): $(param solid_fraction)"
else
  echo "solid fraction (both, fixed volume): $(param solid_fraction)"
fi

# Mean and batch standard error of tau, p_yy, p, tau / p_yy, tau / p and the solid fraction of
# one stress series (columns: step pxx pyy pzz pxy pxz pyz solid_fraction; the last 0 in files
# written before it was recorded).
reduce() {
  awk -v dt="$dt" -v rate="$rate" -v discard="$discard" -v nb="$batches" -v name="$2" '
    /^#/ {next}
    NF >= 7 && $1 * dt * rate > discard {n++; xx[n] = $2; yy[n] = $3; zz[n] = $4; xy[n] = $5; phi[n] = $8}
    END {
      per = int(n / nb)
      for (b = 0; b < nb; b++) {
        t = 0; y = 0; p = 0; f = 0
        for (i = b * per + 1; i <= (b + 1) * per; i++) {t -= xy[i]; y += yy[i]; p += (xx[i] + yy[i] + zz[i]) / 3; f += phi[i]}
        v[1, b] = t / per; v[2, b] = y / per; v[3, b] = p / per
        v[4, b] = t / y; v[5, b] = t / p; v[6, b] = f / per
      }
      printf "%s", name
      for (q = 1; q <= 6; q++) {
        m = 0; for (b = 0; b < nb; b++) m += v[q, b]; m /= nb
        s = 0; for (b = 0; b < nb; b++) s += (v[q, b] - m) ^ 2
        printf " %.6g %.6g", m, sqrt(s / (nb - 1) / nb)
      }
      printf " %d\n", n
    }' "$1"
}
m=$(reduce "$work/millflow_stress.txt" millflow)
l=$(reduce "$work/lammps_stress.txt" LAMMPS)
awk -v m="$m" -v l="$l" -v discard="$discard" -v nb="$batches" -v held="$stress_control" 'BEGIN {
  split(m, a); split(l, b)
  split("tau_Pa p_yy_Pa p_Pa tau/p_yy tau/p", names)
  printf "after %g strain, %d batches (%d and %d samples)\n", discard, nb, a[14], b[14]
  if (a[14] < nb || b[14] < nb) {print "too few samples: FAIL"; exit 1}
  printf "%-10s %24s %24s %8s %8s\n", "quantity", "millflow", "LAMMPS", "diff %", "diff/se"
  pass = 1
  for (q = 1; q <= 5; q++) {
    mm = a[2 * q]; ms = a[2 * q + 1]; lm = b[2 * q]; ls = b[2 * q + 1]
    d = 100 * (mm - lm) / lm
    printf "%-10s %12.6g +- %-9.3g %12.6g +- %-9.3g %+8.2f %+8.1f\n", names[q], mm, ms, lm, ls, d, (mm - lm) / sqrt(ms ^ 2 + ls ^ 2)
    if (q >= 4 && (d > 3 || d < -3)) pass = 0
  }
  print (pass ? "friction within 3%: PASS" : "friction within 3%: FAIL")
  if (held) {
    mm = a[12]; ms = a[13]; lm = b[12]; ls = b[13]; d = mm - lm
    printf "%-10s %12.6g +- %-9.3g %12.6g +- %-9.3g %+8.4f %+8.1f  (diff absolute)\n", "phi", mm, ms, lm, ls, d, d / sqrt(ms ^ 2 + ls ^ 2)
    print ((d <= 0.01 && d >= -0.01) ? "solid fraction within 0.01: PASS" : "solid fraction within 0.01: FAIL")
  }
}'

if ((with_powder)); then
  # LAMMPS's contact rows (types, r, F_n, F_t on the first atom, x_1 - x_2) reduced per dump to
  # millflow_contacts.txt's columns: per pair type (1-1, 1-2, 2-2) contacts, mean overlap /
  # smaller diameter, and (1/V) sum of F (x) (x_1 - x_2) symmetrised (xx yy zz xy xz yz).
  [[ -e $work/lammps_contacts.dump ]] && awk -v d1="$(param media_diameter)" -v d2="$(param powder_diameter)" -v vol="$(param volume)" '
    function flush(  t, k) {
      if (step == "") return
      printf "%s", step
      for (t = 0; t < 3; t++) {
        printf " %d %.8g", n[t], (n[t] > 0 ? ov[t] / n[t] : 0)
        for (k = 1; k <= 6; k++) printf " %.10g", s[t, k] / vol
      }
      printf "\n"
      for (t = 0; t < 3; t++) {n[t] = 0; ov[t] = 0; for (k = 1; k <= 6; k++) s[t, k] = 0}
    }
    /^ITEM: TIMESTEP/ {flush(); rows = 0; getline; step = $1; next}
    /^ITEM: ENTRIES/ {rows = 1; next}
    /^ITEM:/ {rows = 0; next}
    rows {
      t = $1 + $2 - 2; da = ($1 == 1) ? d1 : d2; db = ($2 == 1) ? d1 : d2
      r = $3; fx = $4 * $8 / r + $5; fy = $4 * $9 / r + $6; fz = $4 * $10 / r + $7
      n[t]++; ov[t] += (0.5 * (da + db) - r) / (da < db ? da : db)
      s[t, 1] += fx * $8; s[t, 2] += fy * $9; s[t, 3] += fz * $10
      s[t, 4] += 0.5 * (fx * $9 + fy * $8); s[t, 5] += 0.5 * (fx * $10 + fz * $8)
      s[t, 6] += 0.5 * (fy * $10 + fz * $9)
    }
    END {flush()}' "$work/lammps_contacts.dump" >"$work/lammps_contacts.txt"
  rm -f "$work/lammps_contacts.dump"
  particles=$(awk -v m="$(param media_count)" -v p="$(param powder_count)" 'BEGIN {print m + p}')
  # Per batch, from the batch means: each type's share of the contacts' tau and p, its contacts per
  # particle and mean overlap; mean and standard error over the batches.
  reduce_contacts() {
    awk -v dt="$dt" -v rate="$rate" -v discard="$discard" -v nb="$batches" -v np="$particles" '
      /^#/ {next}
      NF >= 25 && $1 * dt * rate > discard {
        c++
        for (t = 0; t < 3; t++) {b = 2 + 8 * t; z[c, t] = $b; o[c, t] = $(b + 1); xy[c, t] = $(b + 5)
                                  tr[c, t] = ($(b + 2) + $(b + 3) + $(b + 4)) / 3}
      }
      END {
        per = int(c / nb)
        for (q = 0; q < 12; q++) for (k = 0; k < nb; k++) v[q, k] = 0
        for (k = 0; k < nb; k++) {
          sxy = 0; str = 0
          for (t = 0; t < 3; t++) {
            a = 0; p = 0; zz = 0; oo = 0
            for (i = k * per + 1; i <= (k + 1) * per; i++) {a += xy[i, t]; p += tr[i, t]; zz += z[i, t]; oo += o[i, t]}
            txy[t] = a; ttr[t] = p; sxy += a; str += p
            v[6 + t, k] = 2 * zz / per / np; v[9 + t, k] = oo / per
          }
          for (t = 0; t < 3; t++) {v[t, k] = txy[t] / sxy; v[3 + t, k] = ttr[t] / str}
        }
        for (q = 0; q < 12; q++) {
          m = 0; for (k = 0; k < nb; k++) m += v[q, k]; m /= nb
          s = 0; for (k = 0; k < nb; k++) s += (v[q, k] - m) ^ 2
          printf " %.6g %.6g", m, sqrt(s / (nb - 1) / nb)
        }
        printf " %d\n", c
      }' "$1"
  }
  mc=$(reduce_contacts "$work/millflow_contacts.txt")
  lc=$(reduce_contacts "$work/lammps_contacts.txt")
  awk -v m="$mc" -v l="$lc" 'BEGIN {
    split(m, a); split(l, b)
    split("mm mp pp", types)
    for (t = 1; t <= 3; t++) {
      names[t] = "tau share " types[t]; names[3 + t] = "p share " types[t]
      names[6 + t] = "z " types[t]; names[9 + t] = "overlap " types[t]
    }
    printf "contacts: %d and %d samples; shares of the contact stress, contacts per particle z, mean overlap / d_min\n", a[25], b[25]
    pass = 1
    for (q = 1; q <= 12; q++) {
      mm = a[2 * q - 1]; ms = a[2 * q]; lm = b[2 * q - 1]; ls = b[2 * q]
      d = lm != 0 ? 100 * (mm - lm) / lm : 0; se = sqrt(ms ^ 2 + ls ^ 2)
      sep = se > 0 ? (mm - lm) / se : 0
      printf "%-14s %12.6g +- %-9.3g %12.6g +- %-9.3g %+8.2f %+8.1f\n", names[q], mm, ms, lm, ls, d, sep
      if (q <= 6 && (sep > 2 || sep < -2)) pass = 0
    }
    print (pass ? "stress shares within 2 se: PASS" : "stress shares within 2 se: FAIL")
  }'
fi
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
