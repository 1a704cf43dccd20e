#!/usr/bin/env python3
"""Markdown tables of a `fascicle bench decompose --json F` run, for docs/BENCHMARKS.md."""
import json
import sys

run = json.load(open(sys.argv[1]))


def row(name, r):
    if r["status"] == "error":
        return f"| {name} | error | | | | | {r['seconds']:.2f} | {r['error'][:90]} |"
    q = r["quality"]
    fails = []
    if q["inside_fraction"] < 1.0:
        fails.append("inside")
    if q["inverted_cells"] > 0:
        fails.append("inverted")
    if q["coverage_p95"] > 2.0:
        fails.append("coverage")
    if q["attachment"] > 0.02:
        fails.append("attachment")
    return (f"| {name} | {r['status']} | {q['inside_fraction']:.6g} | {q['inverted_cells']} | "
            f"{q['coverage_p95']:.2f} | {q['attachment']:.4f} | {r['seconds']:.2f} | {', '.join(fails)} |")


head = "| muscle | status | inside | inverted cells | coverage p95 | attachment | s | fails |\n|---|---|---|---|---|---|---|---|"
for s in run.get("speed", []):
    print(f"- speed, {s['muscle']} ({s['vertices']} vertices, {s['triangles']} triangles), median of {s['repeat']}: "
          f"sphere {s['sphere_seconds']:.3f} s, placement {s['placement_seconds']:.3f} s, settle {s['settle_seconds']:.3f} s, "
          f"output {s['output_seconds']:.3f} s, check {s['check_seconds']:.3f} s; total {s['median_seconds']:.3f} s wall, "
          f"{s['median_cpu_seconds']:.3f} s CPU; without the check {s['median_without_check_seconds']:.3f} s wall.")
if run.get("templates"):
    print("\nLHDL muscles with their landmark files, every template:\n")
    print(head)
    for r in run["templates"]:
        print(row(f"{r['muscle']} {r['template']}", r))
if run.get("corpus"):
    print(f"\nCorpus, default options (parallel template, automatic areas), with repair: "
          f"{run['corpus_pass']} of {len(run['corpus'])} pass every criterion; {run['corpus_seconds']:.0f} s one after another.\n")
    print(head)
    for r in run["corpus"]:
        print(row(r["muscle"], r))
