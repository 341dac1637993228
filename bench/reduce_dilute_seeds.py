#!/usr/bin/env python3
"""Table 3 of docs/cell_validation.md over several seeds: dilute powder against media only.

Reads the output of `bench_cell_physics --tables 3 --seed N` for several N (one file each) and
prints, for tau / p_yy and tau / p:
  - each seed's bench comparison (media-only friction interpolated to the dilute cell's I), and
    their mean weighted by 1 / se^2;
  - the media-only friction fitted linearly in I over every media-only cell of every seed
    (weighted by 1 / se^2, errors scaled by sqrt(chi^2 / dof) when that exceeds 1), at the dilute
    cells' mean I, against the dilute cells' weighted mean; once with all media-only cells and once
    with those whose barostat held p_yy within --tolerance of the target (the dilute cells do).

    python3 bench/reduce_dilute_seeds.py t3_seed*.txt [--target 2e4] [--tolerance 0.05]
"""
import argparse
import math
import re

CELL = re.compile(r"cell LE load ([\d.]+), ([\d.]+) 1/s.*?; I ([\d.]+), p_yy ([\d.e+]+) Pa, "
                  r"p ([\d.e+]+) Pa")
NUMBER = r"\s+([\d.]+) \+- ([\d.]+)\s+([\d.]+) \+- ([\d.]+)"
ROWS = {"tau/p_yy": ("friction (site rate)", "friction (equal I)", "friction (interpolated)"),
        "tau/p": ("friction_mean_p (site)", "friction_mean_p (eq. I)", "friction_mean_p (interp)")}


def row(text, name):
    match = re.search(re.escape(name) + NUMBER, text)
    return tuple(map(float, match.groups())) if match else None


def weighted_mean(values):
    weights = [1.0 / e ** 2 for _, e in values]
    mean = sum(w * v for w, (v, _) in zip(weights, values)) / sum(weights)
    return mean, 1.0 / math.sqrt(sum(weights))


def line_fit(points, at):
    """Weighted y = a + b (x - at) over (x, y, se); value and error at x = at, chi^2, dof."""
    sw = sx = sxx = sy = sxy = 0.0
    for x, y, e in points:
        w, dx = 1.0 / e ** 2, x - at
        sw, sx, sxx, sy, sxy = sw + w, sx + w * dx, sxx + w * dx * dx, sy + w * y, sxy + w * dx * y
    det = sw * sxx - sx * sx
    b = (sw * sxy - sx * sy) / det
    a = (sy - b * sx) / sw
    chi2 = sum(((y - a - b * (x - at)) / e) ** 2 for x, y, e in points)
    dof = len(points) - 2
    scale = math.sqrt(max(1.0, chi2 / dof)) if dof > 0 else 1.0
    return a, math.sqrt(sxx / det) * scale, chi2, dof


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+")
    parser.add_argument("--target", type=float, default=2e4, help="site normal stress, Pa")
    parser.add_argument("--tolerance", type=float, default=0.05, help="p_yy within this of target")
    args = parser.parse_args()
    runs = []
    for path in args.files:
        with open(path) as f:
            text = f.read()
        cells = CELL.findall(text)
        if len(cells) < 3:
            raise SystemExit(f"{path}: not a finished table 3 (found {len(cells)} cells)")
        runs.append((path, text, [tuple(map(float, c)) for c in cells[:3]]))
    for quantity, (site, matched, interpolated) in ROWS.items():
        print(f"{quantity}:")
        diffs, media, dilute = [], [], []
        for path, text, cells in runs:
            s, m, i = row(text, site), row(text, matched), row(text, interpolated)
            dilute.append((cells[0][2], s[2], s[3]))
            media += [(cells[1][2], s[0], s[1], cells[1][3]), (cells[2][2], m[0], m[1], cells[2][3])]
            if i:
                d, e = i[2] - i[0], math.hypot(i[1], i[3])
                diffs.append((d, e))
                print(f"  {path}: interpolated media {i[0]:.4f} +- {i[1]:.4f}, dilute {i[2]:.4f} "
                      f"+- {i[3]:.4f}: {d:+.4f} ({100 * d / i[0]:+.2f}%, {d / e:+.1f} se)")
            else:
                print(f"  {path}: the media-only cells do not bracket the dilute cell's I")
        if diffs:
            d, e = weighted_mean(diffs)
            print(f"  seeds' weighted mean difference {d:+.4f} +- {e:.4f} ({d / e:+.1f} se)")
        at = sum(x for x, _, _ in dilute) / len(dilute)
        dil, dil_error = weighted_mean([(y, e) for _, y, e in dilute])
        for label, keep in (("all media-only cells", lambda p: True),
                            (f"media-only cells with p_yy within {100 * args.tolerance:g}%",
                             lambda p: abs(p[3] - args.target) <= args.tolerance * args.target)):
            chosen = [(x, y, e) for x, y, e, p in media if keep((x, y, e, p))]
            if len(chosen) < 3:
                print(f"  {label}: {len(chosen)} cells, too few to fit")
                continue
            value, error, chi2, dof = line_fit(chosen, at)
            d, e = dil - value, math.hypot(error, dil_error)
            print(f"  {label} ({len(chosen)}, I {min(c[0] for c in chosen):.3f}-"
                  f"{max(c[0] for c in chosen):.3f}, chi^2 {chi2:.1f} over {dof}): media "
                  f"{value:.4f} +- {error:.4f} at I {at:.4f}, dilute {dil:.4f} +- {dil_error:.4f}: "
                  f"{d:+.4f} ({100 * d / value:+.2f}%, {d / e:+.1f} se)")


if __name__ == "__main__":
    main()
