#!/usr/bin/python3
"""Checks every SVG figure in a directory the way a reader sees it: rsvg-convert (librsvg2-bin)
renders it to a PNG of the canvas' size, and no text runs outside the canvas or over another
text. Text boxes come from the SVG's own text elements (position, anchor, font size, rotation,
the translations of enclosing groups) with report/svg_plot.hpp's estimate of a label's extent:
0.64 em per character, 0.75 em above the baseline and 0.22 em below.

usage: check_svg_text.py DIR
Exit 0 when every figure passes, 1 with a message per failure, 77 when rsvg-convert is missing."""
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

CHAR_EM, ASCENT_EM, DESCENT_EM = 0.64, 0.75, 0.22
SVG = "{http://www.w3.org/2000/svg}"
TOLERANCE = 0.5  # px: boxes that only touch do not overlap


def translate_of(element):
    match = re.match(r"translate\(([-\d.]+)[ ,]+([-\d.]+)\)", element.get("transform", ""))
    return (float(match.group(1)), float(match.group(2))) if match else (0.0, 0.0)


def text_boxes(element, offset=(0.0, 0.0), font_size=12.0, out=None):
    out = [] if out is None else out
    font_size = float(element.get("font-size", font_size))
    if element.tag == SVG + "text":
        content = "".join(element.itertext())
        x, y = float(element.get("x")), float(element.get("y"))
        width = len(content) * CHAR_EM * font_size
        anchor = element.get("text-anchor", "start")
        x0 = x - {"start": 0.0, "middle": width / 2, "end": width}[anchor]
        box = [x0, y - ASCENT_EM * font_size, x0 + width, y + DESCENT_EM * font_size]
        rotation = re.match(r"rotate\(-90 ([-\d.]+) ([-\d.]+)\)", element.get("transform", ""))
        if rotation:  # (x, y) -> (cx + (y - cy), cy - (x - cx))
            cx, cy = float(rotation.group(1)), float(rotation.group(2))
            xs = [cx + (box[1] - cy), cx + (box[3] - cy)]
            ys = [cy - (box[0] - cx), cy - (box[2] - cx)]
            box = [min(xs), min(ys), max(xs), max(ys)]
        box = [box[0] + offset[0], box[1] + offset[1], box[2] + offset[0], box[3] + offset[1]]
        out.append((content, box))
        return out
    dx, dy = translate_of(element)
    for child in element:
        text_boxes(child, (offset[0] + dx, offset[1] + dy), font_size, out)
    return out


def png_size(path):
    with open(path, "rb") as png:
        header = png.read(24)
    return struct.unpack(">II", header[16:24])


def check_figure(path, scratch):
    failures = []
    root = ET.parse(path).getroot()
    width, height = float(root.get("width")), float(root.get("height"))
    png = os.path.join(scratch, os.path.basename(path) + ".png")
    rendered = subprocess.run(["rsvg-convert", "-o", png, path], capture_output=True, text=True)
    if rendered.returncode != 0:
        return [f"{path}: rsvg-convert failed: {rendered.stderr.strip()}"]
    rendered_width, rendered_height = png_size(png)
    if abs(rendered_width - width) >= 1 or abs(rendered_height - height) >= 1:
        failures.append(f"{path}: rendered {png_size(png)}, canvas {width} x {height}")
    boxes = text_boxes(root)
    for content, (x0, y0, x1, y1) in boxes:
        if x0 < -TOLERANCE or y0 < -TOLERANCE or x1 > width + TOLERANCE or y1 > height + TOLERANCE:
            failures.append(f"{path}: \"{content}\" runs outside the {width:g} x {height:g} "
                            f"canvas ({x0:.1f}, {y0:.1f}, {x1:.1f}, {y1:.1f})")
    for i, (a, box_a) in enumerate(boxes):
        for b, box_b in boxes[i + 1:]:
            if (box_a[0] < box_b[2] - TOLERANCE and box_b[0] < box_a[2] - TOLERANCE and
                    box_a[1] < box_b[3] - TOLERANCE and box_b[1] < box_a[3] - TOLERANCE):
                failures.append(f"{path}: \"{a}\" and \"{b}\" overlap")
    return failures


def main(directory):
    if shutil.which("rsvg-convert") is None:
        print("rsvg-convert is missing (Debian: librsvg2-bin); skipped")
        return 77
    figures = sorted(f for f in os.listdir(directory) if f.endswith(".svg"))
    failures = []
    with tempfile.TemporaryDirectory() as scratch:
        for figure in figures:
            failures += check_figure(os.path.join(directory, figure), scratch)
    for failure in failures:
        print("FAIL", failure)
    print(f"{len(figures)} figures rendered and checked, {len(failures)} failure(s)")
    return 1 if failures or not figures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
