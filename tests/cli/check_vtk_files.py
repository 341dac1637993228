#!/usr/bin/python3
"""Reads every VTK file `millflow files CAMPAIGN --out DIR` wrote with VTK's own readers and checks
what a ParaView user relies on: every collection entry loads, point counts and arrays are the
expected ones, the particle ids are the same set in every frame, and the mill outline of each
frame is turned to the shell's angle at that frame's time.

usage: check_vtk_files.py DIR DATABASE
Exit 0 when all checks pass, 1 with a message per failure, 77 when VTK's Python modules are
missing (python3-vtk9)."""
import csv
import json
import math
import os
import sqlite3
import sys
import xml.etree.ElementTree as ET

try:
    from vtkmodules.vtkIOXML import vtkXMLImageDataReader, vtkXMLPolyDataReader
except ImportError:
    print("VTK's Python modules are missing (Debian: python3-vtk9); skipped")
    sys.exit(77)

failures = []


def check(condition, message):
    if not condition:
        failures.append(message)
    return condition


def read(reader_class, path):
    reader = reader_class()
    reader.SetFileName(path)
    reader.Update()
    return reader.GetOutput()


def point_array(data, name):
    array = data.GetPointData().GetArray(name)
    return [array.GetTuple(k) for k in range(array.GetNumberOfTuples())] if array else None


def collection(pvd):
    root = ET.parse(pvd).getroot()
    return [(float(d.get("timestep")), os.path.join(os.path.dirname(pvd), d.get("file")))
            for d in root.iter("DataSet")]


def check_macro(folder, result, params):
    n_balls = result["n_balls"]
    omega = result["angular_velocity_rad_s"]
    settle = params["macro"]["settle_time"]
    dt = result["dt_s"]
    particles = collection(os.path.join(folder, "vtk", "particles.pvd"))
    outlines = collection(os.path.join(folder, "vtk", "mill.pvd"))
    check(len(particles) >= 3, f"{folder}: {len(particles)} particle frames, expected at least 3")
    check([t for t, _ in particles] == [t for t, _ in outlines],
          f"{folder}: the particle and mill collections have different times")
    for time, path in particles:
        data = read(vtkXMLPolyDataReader, path)
        if not check(data.GetNumberOfPoints() == n_balls,
                     f"{path}: {data.GetNumberOfPoints()} points, expected {n_balls}"):
            continue
        ids = sorted(int(v[0]) for v in point_array(data, "id"))
        check(ids == list(range(n_balls)), f"{path}: ids are not 0..{n_balls - 1}")
        for name, components in (("radius", 1), ("velocity", 3), ("angular_velocity", 3),
                                 ("material", 1)):
            array = data.GetPointData().GetArray(name)
            check(array is not None and array.GetNumberOfComponents() == components and
                  array.GetNumberOfTuples() == n_balls, f"{path}: array {name} missing or wrong")
        radii = point_array(data, "radius")
        check(all(abs(r[0] - 0.006) < 1e-6 for r in radii), f"{path}: radii are not 6 mm")
        check(data.GetNumberOfVerts() == 1, f"{path}: expected one vertex cell")
        inside = all(math.hypot(*data.GetPoint(k)[:2]) < 0.1 for k in range(n_balls))
        check(inside, f"{path}: a ball lies outside the 0.2 m mill")
    for time, path in outlines:
        data = read(vtkXMLPolyDataReader, path)
        check(data.GetNumberOfPoints() == 1440 and data.GetNumberOfLines() == 2,
              f"{path}: {data.GetNumberOfPoints()} points and {data.GetNumberOfLines()} lines, "
              "expected 1440 and 2")
        angle = data.GetFieldData().GetArray("angle_rad")
        if not check(angle is not None, f"{path}: no angle_rad field data"):
            continue
        expected = omega * max(0.0, time - settle)
        check(abs(angle.GetValue(0) - expected) <= 2 * omega * dt,
              f"{path}: the shell is at {angle.GetValue(0):.4f} rad at t = {time}, expected "
              f"{expected:.4f} (it must turn with the particles)")
        radii = [math.hypot(*data.GetPoint(k)[:2]) for k in range(720)]
        check(abs(max(radii) - 0.1) < 1e-6 and abs(min(radii) - 0.09) < 2e-3,
              f"{path}: outline radii {min(radii):.4f}..{max(radii):.4f}, expected the liner at "
              "0.1 m and the lifter tops near 0.09 m")
    return len(particles) + len(outlines)


def check_image(path, cells):
    data = read(vtkXMLImageDataReader, path)
    check(data.GetNumberOfCells() == cells,
          f"{path}: {data.GetNumberOfCells()} cells, expected {cells}")
    check(data.GetCellData().GetNumberOfArrays() > 0, f"{path}: no cell arrays")
    return 1


def main(out_dir, db_path):
    db = sqlite3.connect(db_path)
    checked = 0
    kinds = set()
    with open(os.path.join(out_dir, "tasks.csv")) as index:
        for row in csv.DictReader(index):
            folder = os.path.join(out_dir, row["folder"])
            kinds.add(row["kind"])
            params, result = db.execute("SELECT params, result FROM tasks JOIN results ON "
                                        "results.task_key = tasks.key WHERE key = ?",
                                        (row["task_key"],)).fetchone()
            params, result = json.loads(params), json.loads(result)
            check(row["fill"] == "0.3" and row["speed_fraction"] == "0.75",
                  f"tasks.csv: {row['kind']} at fill {row['fill']}, speed {row['speed_fraction']}")
            if row["kind"] == "macro":
                checked += check_macro(folder, result, params)
            elif row["kind"] == "average":
                checked += check_image(os.path.join(folder, "fields.vti"), 20 * 20)
            elif row["kind"] == "sites":
                checked += check_image(os.path.join(folder, "regions.vti"), 20 * 20)
    check(kinds == {"macro", "average", "sites"}, f"tasks.csv lists the kinds {sorted(kinds)}")
    for failure in failures:
        print("FAIL", failure)
    print(f"{checked} VTK files read, {len(failures)} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
