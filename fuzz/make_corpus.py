#!/usr/bin/env python3
"""Builds the seed corpus of one fuzz target in a scratch folder (never in the repository).

Seeds: the hand-written files under fuzz/seeds/<target>/ and the files of the target's format
under the shared corpus (../shared/data). Files above --max-bytes are cut down so that
mutations stay fast: text files keep their first --max-bytes bytes (the header and the first
records, enough to reach every parser state); binary STL keeps its first facets with the
facet count rewritten to match.

Usage: make_corpus.py TARGET DATA_DIR OUT_DIR [--max-bytes N]
"""
import argparse
import hashlib
import os
import struct
import sys

EXTENSIONS = {
    "off": [".off"], "obj": [".obj"], "stl_ascii": [".stl"], "stl_binary": [".stl"], "ply": [".ply"],
    "vtk": [".vtk"], "thesis": [".txt"], "points": [".xyz"], "polylines": [".vtk", ".obj"],
}


def is_ascii_stl(head: bytes) -> bool:
    return head.lstrip().lower().startswith(b"solid") and b"\0" not in head[:4096]


def reduce(target: str, data: bytes, max_bytes: int) -> bytes:
    if len(data) <= max_bytes:
        return data
    if target == "stl_binary" and len(data) >= 84:
        facets = max(1, (max_bytes - 84) // 50)
        return data[:80] + struct.pack("<I", facets) + data[84:84 + 50 * facets]
    return data[:max_bytes]


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("target")
    parser.add_argument("data_dir")
    parser.add_argument("out_dir")
    parser.add_argument("--max-bytes", type=int, default=16384)
    args = parser.parse_args()
    exts = EXTENSIONS[args.target]
    os.makedirs(args.out_dir, exist_ok=True)
    sources = []
    seeds = os.path.join(os.path.dirname(os.path.abspath(__file__)), "seeds", args.target)
    for name in sorted(os.listdir(seeds)):
        sources.append(os.path.join(seeds, name))
    if os.path.isdir(args.data_dir):
        for root, _, files in os.walk(args.data_dir):
            for name in sorted(files):
                if os.path.splitext(name)[1].lower() in exts:
                    sources.append(os.path.join(root, name))
    written = 0
    for path in sources:
        with open(path, "rb") as f:
            data = f.read()
        if args.target.startswith("stl_") and not path.startswith(seeds):
            if is_ascii_stl(data[:4096]) != (args.target == "stl_ascii"):
                continue
        if args.target == "thesis" and not path.startswith(seeds):
            continue  # the corpus's .txt files are licences and notes, not models
        data = reduce(args.target, data, args.max_bytes)
        digest = hashlib.sha1(data).hexdigest()
        with open(os.path.join(args.out_dir, digest), "wb") as f:
            f.write(data)
        written += 1
    print(f"{args.target}: {written} seeds from {len(sources)} files in {args.out_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
