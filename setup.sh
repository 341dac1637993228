#!/usr/bin/env bash
# One entry point for a fresh Debian 12 machine (README.md, "Getting started").
#   ./setup.sh run   install what is missing, build the program (Release), run the default campaign
#                    (campaigns/quick.json) and print its power draw table
#   ./setup.sh test  install what is missing, build (Release), run every CTest test
# Environment: BUILD_DIR (default build), JOBS (default: nproc).
set -euo pipefail
cd "$(dirname "$0")"
mode=${1:-}
build_dir=${BUILD_DIR:-build}
jobs=${JOBS:-$(nproc)}

packages=(build-essential cmake ninja-build ccache git pkg-config
          libtbb-dev libeigen3-dev libsqlite3-dev sqlite3 nlohmann-json3-dev libfmt-dev libspdlog-dev
          libgtest-dev libgmock-dev libbenchmark-dev libcli11-dev libssl-dev python3 python3-jsonschema)
# The tests also start a private Slurm cluster (tests/slurm/run_slurm_test.sh), check the
# sources against .clang-format, read the VTK files with VTK's own readers (python3-vtk9) and
# render the report's figures (librsvg2-bin).
test_packages=(slurm-wlm munge clang-format python3-vtk9 librsvg2-bin)

install_missing() {
  local missing=()
  for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "setup.sh: installing ${missing[*]}"
  local sudo=""
  [ "$(id -u)" -eq 0 ] || sudo=sudo
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
}

# build [TARGET...]: configure, then build the targets (default: everything, tests included).
build() {
  cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DMILLFLOW_WERROR=ON
  cmake --build "$build_dir" -j "$jobs" ${1:+--target "$@"}
}

case "$mode" in
  run)
    install_missing
    build millflow  # only the program: the first result comes before the tests are compiled
    # The default campaign: local executor, ./millflow.db, no server. Finished tasks are cached,
    # so running it again only prints the results.
    "$build_dir/millflow" submit campaigns/quick.json --jobs "$jobs"
    "$build_dir/millflow" query "SELECT fill, speed_fraction, round(power_kw, 3) AS power_kw,
        round(power_kw_per_t_balls, 2) AS kw_per_t, round(torque_arm_power_kw, 3) AS torque_arm_kw,
        round(toe_angle_deg) AS toe_deg, round(shoulder_angle_deg) AS shoulder_deg, n_balls
        FROM macro_results WHERE campaign = 'quick' ORDER BY fill, speed_fraction"
    # A row per sweep point and upscaling (the cells' own power, or anchored to the macro run's
    # dissipation): their powder power, dominant region and cushioning differ.
    "$build_dir/millflow" query "SELECT fill, speed_fraction, powder_load, method,
        round(power_draw_with_powder_w) AS draw_with_powder_w, round(mill_powder_power_w, 1) AS
        powder_w, dominant_region, round(coupling_median_ratio, 2) AS coupling,
        group_concat(region || ' ' || round(cushioning, 2), ', ') AS cushioning_by_region
        FROM upscaled_results WHERE campaign = 'quick'
        GROUP BY task_key, method ORDER BY fill, speed_fraction, powder_load, method"
    "$build_dir/millflow" report quick --out millflow-report
    ;;
  test)
    packages+=("${test_packages[@]}")
    install_missing
    build
    ctest --test-dir "$build_dir" -j "$jobs" --output-on-failure --timeout 600
    ;;
  *)
    echo "usage: ./setup.sh run|test" >&2
    exit 2
    ;;
esac
