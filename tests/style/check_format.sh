#!/usr/bin/env bash
# Fails when a tracked C++ file differs from the project's .clang-format (clang-format 14, Debian 12).
set -euo pipefail
cd "$1"
command -v clang-format >/dev/null || { echo "clang-format not installed"; exit 77; }
git ls-files '*.cpp' '*.hpp' | xargs clang-format --dry-run --Werror
