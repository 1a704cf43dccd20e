#!/usr/bin/env python3
"""Writes a binary PLY holding one muscle plus N tiny disjoint tetrahedra (hostile input for
docs/RELIABILITY.md, "Resource limits": "a million tiny components").

Usage: make_tiny_components.py MUSCLE.off OUT.ply [N]

MUSCLE.off: the muscle as OFF text (`fascicle convert muscle.vtk -o muscle.off`), triangles only.
The N tetrahedra (default 1 000 000, so 4 N triangles) lie on a cubic grid in a slab beside the
muscle's bounding box (spacing 0.002, edge 0.0001 of the muscle's diagonal), so none touches the
muscle or another; together they hold about 2 % of the muscle's area scale (N = 1e6: 0.017 d^2).
Standard library only (no numpy); about 10 s per million tetrahedra.
"""
import math
import struct
import sys
from array import array


def read_off(path):
    with open(path) as f:
        tokens = f.read().split()
    if tokens[0] != "OFF":
        sys.exit(f"{path}: not an OFF file")
    nv, nf = int(tokens[1]), int(tokens[2])
    pos = 4
    points = [tuple(float(t) for t in tokens[pos + 3 * i: pos + 3 * i + 3]) for i in range(nv)]
    pos += 3 * nv
    faces = []
    for _ in range(nf):
        k = int(tokens[pos])
        if k != 3:
            sys.exit(f"{path}: face of {k} corners (triangles only)")
        faces.append((int(tokens[pos + 1]), int(tokens[pos + 2]), int(tokens[pos + 3])))
        pos += 4
    return points, faces


def main():
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    points, faces = read_off(sys.argv[1])
    n = int(sys.argv[3]) if len(sys.argv) == 4 else 1_000_000
    lo = [min(p[k] for p in points) for k in range(3)]
    hi = [max(p[k] for p in points) for k in range(3)]
    d = math.dist(lo, hi)
    side = max(1, math.ceil(n ** (1.0 / 3.0)))
    spacing, edge = 0.002 * d, 0.0001 * d
    x0 = hi[0] + 0.05 * d
    # A tetrahedron with outward faces (corner 0 at the origin, then the three axes).
    corners = ((0.0, 0.0, 0.0), (edge, 0.0, 0.0), (0.0, edge, 0.0), (0.0, 0.0, edge))
    tet_faces = ((0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3))

    coords = array("d")
    for p in points:
        coords.extend(p)
    face_bytes = bytearray()
    for a, b, c in faces:
        face_bytes += struct.pack("<Biii", 3, a, b, c)
    base = len(points)
    face_struct = struct.Struct("<Biii")
    for t in range(n):
        i, j, k = t % side, (t // side) % side, t // (side * side)
        ox, oy, oz = x0 + i * spacing, lo[1] + j * spacing, lo[2] + k * spacing
        for cx, cy, cz in corners:
            coords.extend((ox + cx, oy + cy, oz + cz))
        for a, b, c in tet_faces:
            face_bytes += face_struct.pack(3, base + a, base + b, base + c)
        base += 4
    nv = len(coords) // 3
    nf = len(faces) + 4 * n
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment one muscle ({len(points)} points) and {n} tiny tetrahedra\n"
        f"element vertex {nv}\nproperty double x\nproperty double y\nproperty double z\n"
        f"element face {nf}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    if sys.byteorder != "little":
        coords.byteswap()
    with open(sys.argv[2], "wb") as out:
        out.write(header.encode("ascii"))
        coords.tofile(out)
        out.write(face_bytes)
    print(f"{sys.argv[2]}: {nv} points, {nf} triangles ({n} tetrahedra + {len(faces)} muscle faces)")


if __name__ == "__main__":
    main()
