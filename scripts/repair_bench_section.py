#!/usr/bin/env python3
"""Summary figures of a `fascicle bench repair --json F` run, for docs/BENCHMARKS.md."""
import json
import statistics
import sys

records = json.load(open(sys.argv[1]))
for label, prefix in (("muscles", "muscles/"), ("broken", "broken/")):
    xs = [r for r in records if r["mesh"].startswith(prefix)]
    ok = [r for r in xs if r["exit_code"] == 0]
    wrapped = [r for r in ok if r.get("fallback", {}).get("used")]
    local = [r for r in ok if not r.get("fallback", {}).get("used")]
    refused = [r for r in xs if r["exit_code"] == 12]
    other = [r for r in xs if r["exit_code"] not in (0, 12)]
    print(f"- {label}: {len(xs)} meshes: {len(ok)} verified genus 0 ({len(local)} by local repair, "
          f"{len(wrapped)} by the wrap fallback), {len(refused)} refused with exit code 12, {len(other)} other exits.")
    if local:
        print(f"  Local repair: largest Hausdorff (kept part) {max(r['hausdorff'] for r in local):.4f} of the diagonal; "
              f"median wall {statistics.median(r['seconds'] for r in local):.2f} s, "
              f"max wall {max(r['seconds'] for r in local):.2f} s, max CPU {max(r['cpu_seconds'] for r in local):.2f} s.")
    print(f"  Whole set: {sum(r['wall_seconds'] for r in xs):.0f} s wall, {sum(r['cpu_seconds'] for r in xs):.0f} s CPU.")
