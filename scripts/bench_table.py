#!/usr/bin/env python3
"""Turns the JSON of `fascicle bench repair --json F` into the Markdown table of docs/BENCHMARKS.md."""
import json
import sys

records = json.load(open(sys.argv[1]))
print("| mesh | faces in | faces out | result | wall s | CPU s | Hausdorff (kept part) | Hausdorff (whole input) | fallback |")
print("|---|---:|---:|---|---:|---:|---:|---:|---|")
for r in records:
    fb = r.get("fallback", {})
    fallback = ""
    if fb.get("used"):
        fallback = "wrap, alpha %.3g" % fb.get("alpha", 0)
    elif r.get("exit_code", 0) != 0:
        fallback = (r.get("error") or "").replace("|", "/")[:110]
    def num(key, fmt):
        return fmt % r[key] if key in r else "-"
    print("| %s | %s | %s | %s | %s | %.2f | %s | %s | %s |" % (
        r["mesh"], r.get("faces_in", "-"), r.get("faces_out", "-"), r.get("status", "?"),
        num("seconds", "%.2f"), r.get("cpu_seconds", 0.0), num("hausdorff", "%.4f"),
        num("hausdorff_whole_input", "%.4f"), fallback))
