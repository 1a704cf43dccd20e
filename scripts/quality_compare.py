#!/usr/bin/env python3
"""Compares two runs of scripts/quality_levels.sh muscle by muscle.

Usage: scripts/quality_compare.py BEFORE AFTER
  BEFORE, AFTER: level folders written by quality_levels.sh (OUT/standard, say), each holding
  per muscle MUSCLE.report.json (decompose) and MUSCLE.vtk.check.json (fascicle check --json).

Prints, for each run, the counts over all muscles (decompose passes, whole check passes, muscles
with a segment out, turning over 45 degrees, ends under 0.25; joints over 45 degrees and those
at a fibre's end), then every muscle whose figures differ, and every muscle whose decompose
failed in AFTER. A method change is judged on all of these together: a change that lowers the
turning while a muscle stops passing decompose is not a gain.
"""
import glob
import json
import os
import statistics
import sys


def load(folder, suffix):
    """Every JSON file under folder ending in suffix, by muscle (its path relative to folder)."""
    out = {}
    for path in glob.glob(os.path.join(folder, "**", "*" + suffix), recursive=True):
        try:
            with open(path) as f:
                out[os.path.relpath(path, folder)[: -len(suffix)]] = json.load(f)
        except ValueError:
            pass  # a file half written by a run that was stopped
    return out


def end_share(check):
    return min(check["ends"]["origin"]["share"], check["ends"]["insertion"]["share"])


def figures(check):
    """One muscle's figures: whole check, segments out, largest turn, joints over 45 (end ones),
    smallest end share, coverage p95."""
    turning = check["turning"]
    return (check["pass"], check["crossing_segments"], round(turning["max_deg"]), turning["over_45"],
            turning["end_joints_over_45"], round(end_share(check), 2), round(check["coverage"]["p95"], 2))


def summary(name, checks, reports):
    values = list(checks.values())
    ok = sum(1 for r in reports.values() if r.get("status") == "ok")
    med = lambda xs: statistics.median(xs) if xs else float("nan")
    print(f"{name}: decompose {ok} of {len(reports)}, whole check {sum(c['pass'] for c in values)} of {len(values)}, "
          f"segments out {sum(c['crossing_segments'] > 0 for c in values)}, "
          f"turning > 45 {sum(c['turning']['max_deg'] > 45 for c in values)}, "
          f"ends < 0.25 {sum(end_share(c) < 0.25 for c in values)}, "
          f"joints > 45 {sum(c['turning']['over_45'] for c in values)} "
          f"(at ends {sum(c['turning']['end_joints_over_45'] for c in values)}), "
          f"median largest turn {med([c['turning']['max_deg'] for c in values]):.1f} deg, "
          f"median coverage p95 {med([c['coverage']['p95'] for c in values]):.3f}")


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    before, after = sys.argv[1], sys.argv[2]
    runs = [(folder, load(folder, ".vtk.check.json"), load(folder, ".report.json")) for folder in (before, after)]
    for folder, checks, reports in runs:
        summary(folder, checks, reports)
    (_, a, _), (_, b, reports_b) = runs
    print("muscle: (whole, segments out, largest turn, joints > 45, at ends, end share, coverage p95)")
    for muscle in sorted(set(a) | set(b)):
        fa = figures(a[muscle]) if muscle in a else None
        fb = figures(b[muscle]) if muscle in b else None
        if fa != fb:
            print(f"  {muscle}: {fa} -> {fb}")
    for muscle, report in sorted(reports_b.items()):
        if report.get("status") != "ok":
            print(f"  decompose failed in {after}: {muscle}: {report.get('failure', report.get('status'))}")


if __name__ == "__main__":
    main()
