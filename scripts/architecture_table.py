#!/usr/bin/env python3
"""Fibre architecture against cadaver data: every Visible Human muscle under DATA that has a row in
DATA/architecture/ward2009.csv is decomposed with its `--muscle` preset (two at a time), and its
mean fibre length and pennation are compared with Ward et al. 2009's means: the length within
25 % of Ward's mean, the pennation within Ward's standard deviation (5 degrees where none is
given).

    scripts/architecture_table.py FASCICLE DATA OUT [--markdown FILE]

DATA is ../shared/data; OUT gets each muscle's fibres, report and log, and table.csv; --markdown
writes the table as Markdown. Exit 0 when it ran (whatever passed), 2 on bad arguments.
"""
import argparse
import concurrent.futures
import csv
import json
import os
import re
import subprocess
import sys

# Visible Human file stems (CamelCase, as the files spell them) to Ward's snake_case names.
VISIBLE_HUMAN_NAMES = {
    "AdductorMagnus": "adductor_magnus",
    "BicepsFemorisLong": "biceps_femoris_long_head",
    "BicepsFemorisLongus": "biceps_femoris_long_head",
    "BicepsFemorisShortHead": "biceps_femoris_short_head",
    "GluteusMaximus": "gluteus_maximus",
    "GluteusMedius": "gluteus_medius",
    "Gracilis": "gracilis",
    "Illiacus": "iliacus",
    "PsoasMajor": "psoas",
    "RectusFemoris": "rectus_femoris",
    "Sartorius": "sartorius",
    "Semimembranosus": "semimembranosus",
    "Semitendinosus": "semitendinosus",
    "Semitendonosus": "semitendinosus",
    "Soleus": "soleus",
    "TibialisAnterior": "tibialis_anterior",
    "VastusIntermedius": "vastus_intermedius",
    "VastusLateralis": "vastus_lateralis",
    "VastusMedialis": "vastus_medialis",
}
LENGTH_TOLERANCE = 0.25
DEFAULT_PENNATION_SD = 5.0


def visible_human_muscles(data):
    found = []
    for folder in ("muscles/visible-human", "extra/visible-human"):
        root = os.path.join(data, folder)
        for dirpath, _, files in os.walk(root):
            for name in sorted(files):
                m = re.match(r"(VH[FM]_(?:Left|Right))_Muscle_([A-Za-z]+)_smooth\.stl$", name)
                if m and m.group(2) in VISIBLE_HUMAN_NAMES:
                    found.append((os.path.join(dirpath, name), m.group(1), VISIBLE_HUMAN_NAMES[m.group(2)]))
    return sorted(found)


def run_one(fascicle, out, path, body, muscle):
    stem = f"{body}_{muscle}"
    report = os.path.join(out, stem + ".json")
    with open(os.path.join(out, stem + ".log"), "w") as log:
        code = subprocess.call([fascicle, "-q", "decompose", path, "-o", os.path.join(out, stem + ".vtk"),
                                "--report", report, "--keep-failed", "--muscle", muscle], stdout=log, stderr=log)
    return stem, code, report


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("fascicle")
    parser.add_argument("data")
    parser.add_argument("out")
    parser.add_argument("--markdown")
    args = parser.parse_args()
    ward_path = os.path.join(args.data, "architecture", "ward2009.csv")
    if not os.path.isfile(ward_path):
        print(f"architecture_table: {ward_path} not found", file=sys.stderr)
        return 2
    ward = {row["muscle"]: row for row in csv.DictReader(open(ward_path))}
    muscles = [m for m in visible_human_muscles(args.data) if m[2] in ward]
    os.makedirs(args.out, exist_ok=True)
    rows = []
    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        jobs = [pool.submit(run_one, args.fascicle, args.out, *m) for m in muscles]
        for (path, body, muscle), job in zip(muscles, jobs):
            stem, code, report_path = job.result()
            w = ward[muscle]
            row = {"muscle": stem, "preset": muscle, "exit": code, "ward_length_mm": float(w["fibre_length_cm"]) * 10,
                   "ward_pennation_deg": float(w["pennation_deg"]),
                   "ward_pennation_sd": float(w["pennation_sd_deg"]) if w["pennation_sd_deg"] else DEFAULT_PENNATION_SD}
            try:
                r = json.load(open(report_path))
                a = r["architecture"]
                row.update({"template": r["lattice"]["template"], "status": r["status"],
                            "length_mm": a["fibre_length_m"]["mean"] * 1e3, "pennation_deg": a["pennation_deg"]["mean"],
                            "muscle_length_mm": a["muscle_length_m"] * 1e3,
                            "check_failed": " ".join(r["quality"]["failed"]),
                            "turning_max_deg": r["quality"]["turning"]["max_deg"],
                            "crossing_segments": r["quality"]["crossing_segments"],
                            "seconds": r["seconds"]["total"]})
            except (OSError, KeyError, ValueError) as e:
                row.update({"template": "", "status": "error", "length_mm": float("nan"), "pennation_deg": float("nan"),
                            "muscle_length_mm": float("nan"), "check_failed": str(e), "turning_max_deg": float("nan"),
                            "crossing_segments": -1, "seconds": float("nan")})
            row["length_error"] = row["length_mm"] / row["ward_length_mm"] - 1
            row["length_ok"] = abs(row["length_error"]) <= LENGTH_TOLERANCE
            row["pennation_ok"] = abs(row["pennation_deg"] - row["ward_pennation_deg"]) <= row["ward_pennation_sd"]
            rows.append(row)
    fields = list(rows[0].keys()) if rows else []
    with open(os.path.join(args.out, "table.csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        writer.writerows(rows)
    both = sum(1 for r in rows if r["length_ok"] and r["pennation_ok"])
    summary = (f"{both} of {len(rows)} muscles within 25 % of Ward's fibre length and within its pennation SD "
               f"({sum(r['length_ok'] for r in rows)} length, {sum(r['pennation_ok'] for r in rows)} pennation); "
               f"{sum(r['status'] == 'ok' for r in rows)} pass decompose's check")
    print(summary)
    if args.markdown:
        lines = ["| muscle | template | fibre length mm (Ward) | error | pennation deg (Ward +- SD) | both | check |",
                 "|---|---|---|---|---|---|---|"]
        for r in rows:
            lines.append(f"| {r['muscle']} | {r['template']} | {r['length_mm']:.0f} ({r['ward_length_mm']:.0f}) | "
                         f"{100 * r['length_error']:+.0f} % | {r['pennation_deg']:.1f} ({r['ward_pennation_deg']:.1f} +- "
                         f"{r['ward_pennation_sd']:.1f}) | {'yes' if r['length_ok'] and r['pennation_ok'] else 'no'} | "
                         f"{r['status']}{' (' + r['check_failed'] + ')' if r['check_failed'] else ''} |")
        lines.append("")
        lines.append(summary + ".")
        with open(args.markdown, "w") as f:
            f.write("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
