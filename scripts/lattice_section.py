#!/usr/bin/env python3
"""Draws one cross-section of a fibre set's lattice: the points of fibre level LEVEL (every
fibre's LEVEL-th point) seen in their best-fit plane, joined along the lattice's r lines (blue)
and s lines (green), each cell's diagonal red where the cell is turned over in that plane
(grey where it is not). Shows where the settle crowds or folds the lattice across the muscle,
which a picture of whole fibres hides.

Usage: scripts/lattice_section.py FIBRES.vtk LEVEL OUT.png [--size PIXELS]
  FIBRES.vtk: legacy VTK fibres as fascicle writes them (fibre_r and fibre_s cell arrays), for
  example `fascicle decompose M -o F.vtk --untangle false --second-try false --keep-failed` to
  see the settled lattice before the untangling.
"""
import argparse
import struct
import sys
import zlib

import numpy as np


def read_fibres(path):
    """The fibres as an array (nr, ns, points, 3) from their fibre_r / fibre_s indices."""
    lines = open(path).read().split("\n")
    points, polylines, arrays = None, [], {}
    i = 0
    while i < len(lines):
        words = lines[i].split()
        if words and words[0] == "POINTS":
            count, values = int(words[1]), []
            i += 1
            while len(values) < 3 * count:
                values += lines[i].split()
                i += 1
            points = np.array(values, float).reshape(count, 3)
            continue
        if words and words[0] == "LINES":
            for j in range(int(words[1])):
                polylines.append([int(v) for v in lines[i + 1 + j].split()[1:]])
            i += 1 + int(words[1])
            continue
        if words and words[0] in ("fibre_r", "fibre_s"):
            count, values = int(words[2]), []
            i += 1
            while len(values) < count:
                values += lines[i].split()
                i += 1
            arrays[words[0]] = np.array(values, float).astype(int)
            continue
        i += 1
    if points is None or "fibre_r" not in arrays or "fibre_s" not in arrays:
        sys.exit(f"{path}: not a fascicle fibre file with fibre_r and fibre_s (legacy VTK)")
    lengths = {len(p) for p in polylines}
    if len(lengths) != 1:
        sys.exit(f"{path}: the fibres do not all have the same number of points")
    r, s = arrays["fibre_r"], arrays["fibre_s"]
    grid = np.zeros((r.max() + 1, s.max() + 1, lengths.pop(), 3))
    grid[r, s] = np.array([points[p] for p in polylines])
    return grid


def write_png(path, image):
    height, width, _ = image.shape
    raw = b"".join(b"\x00" + image[y].tobytes() for y in range(height))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    with open(path, "wb") as out:
        out.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("fibres")
    parser.add_argument("level", type=int)
    parser.add_argument("out")
    parser.add_argument("--size", type=int, default=600, help="the picture's longer side in pixels (default 600)")
    args = parser.parse_args()
    grid = read_fibres(args.fibres)
    nr, ns, levels, _ = grid.shape
    if not 0 <= args.level < levels:
        sys.exit(f"level {args.level} is not in [0, {levels - 1}]")
    layer = grid[:, :, args.level]
    flat = layer.reshape(-1, 3)
    centre = flat.mean(axis=0)
    _, _, axes = np.linalg.svd(flat - centre)
    plane = (layer - centre) @ axes[:2].T
    low, high = plane.reshape(-1, 2).min(axis=0), plane.reshape(-1, 2).max(axis=0)
    margin = args.size // 20
    scale = (args.size - 2 * margin) / max((high - low).max(), 1e-300)
    width, height = (np.ceil((high - low) * scale).astype(int) + 2 * margin)
    image = np.full((height, width, 3), 255, np.uint8)

    def pixel(p):
        return (p - low) * scale + margin

    def draw(p, q, colour):
        a, b = pixel(p), pixel(q)
        for t in np.linspace(0.0, 1.0, int(np.abs(b - a).max()) + 2):
            x, y = (a + (b - a) * t).astype(int)
            if 0 <= x < width and 0 <= y < height:
                image[height - 1 - y, x] = colour

    # A cell is turned over when its quad's orientation in the plane is against the layer's.
    signs = np.zeros((nr - 1, ns - 1))
    for i in range(nr - 1):
        for j in range(ns - 1):
            d1 = plane[i + 1, j + 1] - plane[i, j]
            d2 = plane[i, j + 1] - plane[i + 1, j]
            signs[i, j] = d1[0] * d2[1] - d1[1] * d2[0]
    majority = np.sign(np.median(signs)) or 1.0
    for i in range(nr - 1):
        for j in range(ns - 1):
            turned = signs[i, j] * majority <= 0
            draw(plane[i, j], plane[i + 1, j + 1], (200, 0, 0) if turned else (190, 190, 190))
    for i in range(nr):
        for j in range(ns - 1):
            draw(plane[i, j], plane[i, j + 1], (0, 0, 200))
    for j in range(ns):
        for i in range(nr - 1):
            draw(plane[i, j], plane[i + 1, j], (0, 140, 0))
    write_png(args.out, image)
    turned_count = int((signs * majority <= 0).sum())
    print(f"{args.out}: level {args.level} of {levels}, {turned_count} of {signs.size} cells turned over in its plane")


if __name__ == "__main__":
    main()
