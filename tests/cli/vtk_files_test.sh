#!/usr/bin/env bash
# `millflow files` on a small macro-only campaign, read back with VTK's own readers
# (check_vtk_files.py). Exit 77 (skipped) without VTK's Python modules (Debian: python3-vtk9).
# usage: vtk_files_test.sh MILLFLOW
set -euo pipefail
millflow=$1
here=$(cd "$(dirname "$0")" && pwd)
/usr/bin/python3 -c "import vtkmodules.vtkIOXML" 2>/dev/null || {
  echo "python3-vtk9 is not installed; skipped"
  exit 77
}
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
"$millflow" submit "$here/vtk_campaign.json" --db "$scratch/m.db" --jobs 2 >/dev/null 2>"$scratch/err" ||
  { cat "$scratch/err"; exit 1; }
"$millflow" files vtk_files --db "$scratch/m.db" --out "$scratch/files"
/usr/bin/python3 "$here/check_vtk_files.py" "$scratch/files" "$scratch/m.db"
