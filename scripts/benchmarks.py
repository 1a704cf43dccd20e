#!/usr/bin/env python3
"""Writes docs/BENCHMARKS.md from the JSON files of scripts/bench.sh (docs/bench/*.json).

Usage: benchmarks.py BENCH_DIR > docs/BENCHMARKS.md
Each section is one stage: what was measured, the command, the table, and the figure it is
compared with (the thesis's tables, the limit measured in the same run). A missing file leaves
its section saying so.
"""
import json
import os
import statistics
import sys

folder = sys.argv[1]

# The thesis's figures (METHOD.md, chapter 7; a 2011 CPU and an NVIDIA GeForce GTX 280).
THESIS_CPU_MS = {6: 274.0, 26: 907.0}  # ms per Verlet iteration at 100^3
THESIS_GS_MS = 33.7                     # GPU geometry-shader pass, 100^3 model-6
THESIS_READBACK_MS = {"glReadPixels": 28.1, "pbo": 22.6}  # 100^3 positions


def load(name):
    path = os.path.join(folder, name)
    if not os.path.exists(path):
        return None
    with open(path) as f:
        return json.load(f)


def by_section(records):
    out = {}
    for r in records or []:
        out.setdefault(r["section"], []).append(r)
    return out


def num(x, fmt="%.3g"):
    if x is None:
        return "-"
    if isinstance(x, float) and x != x:
        return "-"
    return fmt % x


lines = []
emit = lines.append


def section(title, name):
    """Opens a stage's section; returns the records of docs/bench/NAME, or None (said so) when absent."""
    emit("## " + title)
    emit("")
    data = load(name)
    if data is None:
        emit("Not measured (`docs/bench/%s` is missing)." % name)
        emit("")
    return data

machine = load("machine.json") or {}
where = "%s, %s cores, %s GiB%s" % (
    machine.get("cpu", "?"), machine.get("cores", "?"), machine.get("memory_gib", "?"),
    ", AVX-512" if machine.get("avx512") else (", AVX2" if machine.get("avx2") else ""))

emit("# Benchmarks")
emit("")
emit("Today's figures of every stage, written by `make bench` (`bash scripts/bench.sh build "
     "../shared/data docs/bench`: each bench program into `docs/bench/*.json`, then "
     "`scripts/benchmarks.py docs/bench > docs/BENCHMARKS.md`). Rerunning it replaces them; the "
     "history is in git. Speed figures are wall times: run it on a quiet machine.")
emit("")
emit("Machine: %s; %s; commit %s%s, %s." % (where, machine.get("os", "?"), machine.get("commit", "?"),
                                          " (with local changes)" if machine.get("dirty") else "",
                                          machine.get("date", "?")))
# Parts last measured in an earlier run (`BENCH_SECTIONS`), on another machine or commit.
this_run = {k: machine.get(k) for k in ("cpu", "avx512", "commit", "dirty", "date")}
earlier = {}
for part, stamp in sorted(machine.get("sections", {}).items()):
    if stamp != this_run:
        key = "%s%s, commit %s%s, %s" % (stamp.get("cpu", "?"), ", AVX-512" if stamp.get("avx512") else "",
                                         stamp.get("commit", "?"), " (with local changes)" if stamp.get("dirty") else "",
                                         stamp.get("date", "?"))
        earlier.setdefault(key, []).append(part)
for key, parts in earlier.items():
    emit("")
    emit("Parts from an earlier run (%s): %s." % (key, ", ".join(parts)))
emit("")

# ---------------------------------------------------------------- quality levels and tests
emit("## Quality levels and test tiers")
emit("")
quality = load("quality.json")
if quality:
    emit("`bash scripts/quality_levels.sh build/fascicle ../shared/data/muscles OUT`: for each level "
         "`fascicle -q batch ../shared/data/muscles -o OUT --jobs 2 --quality LEVEL`, timed, then "
         "`fascicle check` (every criterion, default thresholds) on each muscle's fibres. "
         "Decompose judges inside, inverted cells, coverage and attachment; the whole check adds the "
         "segments between points, the turning angle (45 degrees) and the ends' spread (0.25).")
    emit("")
    emit("| level | fibres x points | batch, 2 jobs | per muscle, median / max | decompose passes | "
         "whole check passes | segments out | turning > 45 deg | joints > 45 deg | ends < 0.25 | "
         "median coverage p95 | median largest turning |")
    emit("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for q in quality:
        emit("| %s | %s | %.0f s | %.2f / %.1f s | %d of %d | %d of %d | %d | %d | %d | %d | %.2f | %.0f deg |" % (
            q["level"], q["lattice"], q["batch_seconds"], q["muscle_seconds_median"], q["muscle_seconds_max"],
            q["decompose_ok"], q["muscles"], q["check_pass"], q["checked"], q["segments_out"],
            q["turning_over_45"], q["joints_over_45"], q["ends_under_025"], q["median_coverage_p95"],
            q["median_turning_deg"]))
    emit("")
tests = load("tests.json")
if tests:
    runs = {"unit": "make test", "corpus": "make test-corpus"}
    emit("Test tiers, wall time after the build (%s):" % "; ".join(
        "`ctest -j%s -L %s`, what `%s` runs" % (machine.get("cores", 2), label, runs[label])
        for label in ("unit", "corpus") if label in tests))
    emit("")
    emit("| tier | tests | failed | skipped | wall |")
    emit("|---|---|---|---|---|")
    for label in ("unit", "corpus"):
        t = tests.get(label)
        if t:
            emit("| %s | %s | %s | %s | %.0f s (%.1f min) |" % (label, t["tests"], t["failed"], t["skipped"],
                                                            t["seconds"], t["seconds"] / 60))
    emit("")

# ---------------------------------------------------------------- repair
repair = section("Repair", "repair.json")
if repair is not None:
    emit("`fascicle bench repair --data ../shared/data --json docs/bench/repair.json`: every mesh under "
         "`muscles/`, `broken/` and `extra/` repaired by its own `fascicle -q --time-limit 120 repair IN -o OUT --report R` "
         "process, as a user runs it. Wall s: the repair itself (reading and writing excluded); CPU s: the "
         "process and its alpha-wrap workers. Hausdorff: two-sided, between the output and the part of the input "
         "kept, and the whole input, relative to the bounding-box diagonal.")
    emit("")
    for label, prefix in (("muscles", "muscles/"), ("broken", "broken/"), ("extra", "extra/")):
        xs = [r for r in repair if r["mesh"].startswith(prefix)]
        if not xs:
            continue
        ok = [r for r in xs if r["exit_code"] == 0]
        wrapped = [r for r in ok if r.get("fallback", {}).get("used")]
        local = [r for r in ok if not r.get("fallback", {}).get("used")]
        refused = [r for r in xs if r["exit_code"] == 12]
        other = [r for r in xs if r["exit_code"] not in (0, 12)]
        emit("- **%s**: %d meshes; %d closed genus-0 manifolds (%d by the local repair, %d by the wrap fallback), "
             "%d refused with exit code 12, %d other exits; median wall %.2f s, largest %.2f s; whole set %.0f s wall."
             % (label, len(xs), len(ok), len(local), len(wrapped), len(refused), len(other),
                statistics.median(r["seconds"] for r in xs if "seconds" in r) if any("seconds" in r for r in xs) else 0,
                max((r.get("seconds", 0) for r in xs), default=0), sum(r["wall_seconds"] for r in xs)))
    emit("")
    emit("| mesh | faces in | faces out | result | wall s | CPU s | Hausdorff (kept) | Hausdorff (input) | fallback or error |")
    emit("|---|---:|---:|---|---:|---:|---:|---:|---|")
    for r in repair:
        fb = r.get("fallback", {})
        note = ""
        if fb.get("used"):
            note = "wrap, alpha %.3g" % fb.get("alpha", 0)
        elif r.get("exit_code", 0) != 0:
            note = (r.get("error") or "").replace("|", "/")[:90]
        emit("| %s | %s | %s | %s | %s | %.2f | %s | %s | %s |" % (
            r["mesh"], r.get("faces_in", "-"), r.get("faces_out", "-"), r.get("status", "?"),
            num(r.get("seconds"), "%.2f"), r.get("cpu_seconds", 0.0), num(r.get("hausdorff"), "%.4f"),
            num(r.get("hausdorff_whole_input"), "%.4f"), note))
    emit("")

# ---------------------------------------------------------------- sphere map
sphere = section("Sphere map", "sphere.json")
if sphere is not None:
    emit("`fascicle bench sphere --data ../shared/data --json docs/bench/sphere.json`: speed of the map "
         "and of point location (median of the runs), then every corpus muscle after repair mapped by the "
         "default method beside the thesis's relaxation (`--sphere-method relax`, at most 3000 iterations a "
         "relaxation). Area ratio: (spherical area / 4 pi) / (surface area / total area) per triangle; "
         "log|A|: the mean of its absolute logarithm (0 for an area-preserving map).")
    emit("")
    emit("| case | vertices | triangles | wall s | CPU s | flipped | log\\|A\\| |")
    emit("|---|---:|---:|---:|---:|---:|---:|")
    for s in sphere.get("speed", []):
        q = s.get("report", {}).get("quality", {})
        emit("| %s | %s | %s | %.3f | %.3f | %s | %s |" % (
            s["case"], s.get("vertices", "-"), s.get("triangles", "-"), s["median_seconds"],
            s.get("median_cpu_seconds", 0.0), q.get("flipped", "-"), num(q.get("area_log_mean"), "%.3f")))
    emit("")
    corpus = sphere.get("corpus", [])
    if corpus:
        good = [c for c in corpus if c.get("tutte", {}).get("quality", {}).get("bijective")]
        relax_good = [c for c in corpus if c.get("relax", {}).get("status") == "ok"]
        emit("**%d of %d muscles map bijectively** with the default method (0 flipped, 0 degenerate); the "
             "thesis method: %d of %d." % (len(good), len(corpus), len(relax_good), len(corpus)))
        emit("")
        emit("| muscle | vertices | start | flipped | area ratio min | max | log\\|A\\| | s | relax | flipped | log\\|A\\| | s |")
        emit("|---|---:|---|---:|---:|---:|---:|---:|---|---:|---:|---:|")
        for c in corpus:
            if "error" in c:
                emit("| %s | | error: %s | | | | | | | | | |" % (os.path.basename(c["mesh"]), c["error"][:80]))
                continue
            a = c["tutte"]
            qa = a["quality"]
            b = c.get("relax", {})
            qb = b.get("quality", {})
            emit("| %s | %d | %s | %d | %.2f | %.2f | %.3f | %.2f | %s | %s | %s | %s |" % (
                os.path.basename(c["mesh"]), c["vertices"], a.get("initial_map", "?"), qa["flipped"],
                qa["area_ratio_min"], qa["area_ratio_max"], qa["area_log_mean"], a["seconds"],
                b.get("status", "-"), qb.get("flipped", "-"), num(qb.get("area_log_mean"), "%.3f"),
                num(b.get("seconds"), "%.2f")))
        emit("")

# ---------------------------------------------------------------- springs
springs = by_section(section("Springs (CPU)", "springs.json"))
if springs:
    emit("`fascicle bench springs --sections bandwidth,speed,rest,trade --sizes 10,20,50,100 --general-max-size 50 "
         "--rest-sizes 5,10 --trade-sizes 20,50 --trade-models 6,26 --trade-solvers "
         "verlet-estimate,static-momentum,static-multigrid --trade-limit 60 --json docs/bench/springs.json`.")
    emit("")
    for b in springs.get("bandwidth", []):
        emit("Memory bandwidth in the same run (STREAM-like, %d threads): copy %.1f GB/s, triad %.1f GB/s." %
             (b["threads"], b["copy_gb_per_s"], b["triad_gb_per_s"]))
        emit("")
    speed = springs.get("speed", [])
    if speed:
        emit("### ms per Verlet iteration (thesis tables 7.1, 7.2)")
        emit("")
        emit("n^3 lattice, model-6 (springs to the 6 axis neighbours) or model-26. x stream: against the time "
             "to stream the lattice's data once at the triad bandwidth above; x compute: against the structured "
             "loop on an in-cache lattice, measured in the same run. The thesis's 2011 CPU: %.0f ms (model-6) and "
             "%.0f ms (model-26) at 100^3." % (THESIS_CPU_MS[6], THESIS_CPU_MS[26]))
        emit("")
        emit("| n | model | path | spring loop | ms/iteration | CPU ms | x stream | x compute | thesis / this |")
        emit("|---:|---:|---|---|---:|---:|---:|---:|---:|")
        for r in sorted(speed, key=lambda r: (r["model"], r["backend"], r["n"])):
            thesis = "%.0fx" % (THESIS_CPU_MS[r["model"]] / r["ms_per_iteration"]) if r["n"] == 100 else ""
            emit("| %d | %d | %s | %s | %.3f | %.3f | %s | %s | %s |" % (
                r["n"], r["model"], r["backend"], r.get("spring_loop", "-"), r["ms_per_iteration"],
                r.get("cpu_ms_per_iteration", 0.0), num(r.get("ratio_to_stream"), "%.2f"),
                num(r.get("ratio_to_compute"), "%.2f"), thesis))
        emit("")
    rest = springs.get("rest", [])
    if rest:
        emit("### Verlet iterations to rest against mass and damping (thesis tables 7.4-7.6)")
        emit("")
        emit("Relative residual %g, dt %g. Best c: the damping with the fewest iterations in a scan of 32 "
             "log-spaced values; c (7.2): the thesis's damping estimate; critical: critical damping. -1: not at "
             "rest within the cap." % (rest[0]["tolerance"], rest[0]["dt"]))
        emit("")
        emit("| n | model | mass | best c | iterations | c (7.2) | iterations | critical |")
        emit("|---:|---:|---:|---:|---:|---:|---:|---:|")
        for r in rest:
            emit("| %d | %d | %.3f | %.3f | %d | %.3f | %d | %d |" % (
                r["n"], r["model"], r["mass"], r["best_damping"], r["best_iterations"], r["estimate_damping"],
                r["estimate_iterations"], r["critical_iterations"]))
        emit("")
    trade = springs.get("trade", [])
    if trade:
        emit("### Speed against accuracy")
        emit("")
        emit("Wall seconds until the relative residual reaches each tolerance (limit 60 s a "
             "run; `-`: not reached). The last column compares the static solver with Verlet at 1e-6 on the "
             "same lattice.")
        emit("")
        runs = {}
        for r in trade:
            runs.setdefault((r["n"], r["model"], r["solver"]), {})[r["tolerance"]] = r
        tols = sorted({r["tolerance"] for r in trade}, reverse=True)
        emit("| n | model | solver | " + " | ".join("%g" % t for t in tols) + " | iterations | Verlet / this at %g |" % tols[-1])
        emit("|---:|---:|---|" + "---:|" * len(tols) + "---:|---:|")
        for (n, model, solver), by_tol in sorted(runs.items()):
            cells = []
            for t in tols:
                r = by_tol.get(t)
                cells.append("%.3f" % r["seconds"] if r and r.get("seconds") is not None else "-")
            last = by_tol.get(tols[-1])
            verlet = runs.get((n, model, "verlet-estimate"), {}).get(tols[-1])
            ratio = ""
            if (last and verlet and last.get("seconds") and verlet.get("seconds") and solver != "verlet-estimate"):
                ratio = "%.1fx" % (verlet["seconds"] / last["seconds"])
            emit("| %d | %d | %s | %s | %s | %s |" % (n, model, solver, " | ".join(cells),
                                                   last["iterations"] if last else "-", ratio))
        emit("")

# ---------------------------------------------------------------- GPU
emit("## GPU settle")
emit("")


def gpu_section(records, title, command):
    sec = by_section(records)
    any_record = (sec.get("speed") or sec.get("bandwidth") or [{}])[0]
    emit("### " + title)
    emit("")
    emit("`%s`. Renderer: %s (%s, %s)." % (command, any_record.get("renderer", "?"), any_record.get("gl_version", "?"),
                                          any_record.get("platform", "?")))
    emit("")
    for b in sec.get("bandwidth", []):
        emit("GPU stream bandwidth in the same run (compute-shader copy of %d MiB): %.1f GB/s." %
             (b["bytes"] // 2**20, b["gb_per_second"]))
        emit("")
    speed = sec.get("speed", [])
    if speed:
        emit("| n | model | backend | ms/iteration | GPU MB | x stream | thesis GPU / this |")
        emit("|---:|---:|---|---:|---:|---:|---:|")
        for r in sorted(speed, key=lambda r: (r["model"], r["backend"], r["n"])):
            thesis = ""
            if r["n"] == 100 and r["model"] == 6 and r["backend"].startswith("gl"):
                thesis = "%.0fx" % (THESIS_GS_MS / r["ms_per_iteration"])
            emit("| %d | %d | %s | %.3f | %.1f | %s | %s |" % (
                r["n"], r["model"], r["backend"], r["ms_per_iteration"], r.get("gpu_bytes", 0) / 1e6,
                num(r.get("stream_ratio"), "%.2f"), thesis))
        emit("")
    readback = sec.get("readback", [])
    if readback:
        emit("Readback of the positions (thesis table 7.3: 100^3 %.1f ms with glReadPixels, %.1f ms with a PBO):" %
             (THESIS_READBACK_MS["glReadPixels"], THESIS_READBACK_MS["pbo"]))
        emit("")
        emit("| n | method | ms (best of 3) |")
        emit("|---:|---|---:|")
        for r in readback:
            emit("| %d | %s | %.3f |" % (r["n"], r["method"], r["ms"]))
        emit("")


gpu = load("gpu.json")
if gpu:
    gpu_section(gpu, "This machine", "fascicle bench gpu --sizes 10,20,40 --readback-sizes 50 --min-seconds 0.5 "
                "--stream-mb 64 --json docs/bench/gpu.json")
else:
    emit("Not measured on this machine (`docs/bench/gpu.json` is missing).")
    emit("")
h200 = load("gpu-h200.json")
if h200:
    gpu_section(h200, "NVIDIA H200 (last measured on the device machine, 2026-11-27; kept until a device run replaces it)",
                "fascicle bench gpu --gl-device 0 --json docs/bench/gpu-h200.json")

# ---------------------------------------------------------------- decompose
dec = section("Decompose", "decompose.json")
if dec is not None:
    emit("`fascicle bench decompose --data ../shared/data --repeat 5 --skip-templates --json "
         "docs/bench/decompose.json`: one muscle timed stage by stage (median of the repeats), then every "
         "corpus muscle with default options, one after another in one process. Judged as decompose judges: "
         "inside, inverted cells, coverage p95 <= 2 and attachment <= 0.02 (the whole check's figures per "
         "quality level are in the first section).")
    emit("")
    for s in dec.get("speed", []):
        emit("- **One decomposition**, %s (%d vertices, %d triangles), median of %d: sphere map %.3f s, "
             "placement %.3f s, settle %.3f s, output %.3f s, check %.3f s; total %.3f s wall (%.3f s without "
             "the check), %.3f s CPU." % (
                 s["muscle"], s["vertices"], s["triangles"], s["repeat"], s["sphere_seconds"],
                 s["placement_seconds"], s["settle_seconds"], s["output_seconds"], s["check_seconds"],
                 s["median_seconds"], s["median_without_check_seconds"], s["median_cpu_seconds"]))
    if dec.get("corpus"):
        corpus = dec["corpus"]
        ok = [c for c in corpus if c.get("status") == "ok"]
        seconds = sorted(c["seconds"] for c in corpus)
        emit("- **Corpus**: %d of %d pass, %.0f s in all; per muscle median %.1f s, largest %.1f s." % (
            len(ok), len(corpus), dec.get("corpus_seconds", sum(seconds)), statistics.median(seconds), seconds[-1]))
    emit("")

    def quality_row(name, r):
        if r.get("status") == "error" or "quality" not in r:
            return "| %s | error | | | | | %.2f | %s |" % (name, r.get("seconds", 0), (r.get("error") or "")[:80])
        q = r["quality"]
        fails = [k for k, bad in (("inside", q["inside_fraction"] < 1.0), ("inverted", q["inverted_cells"] > 0),
                                  ("coverage", q["coverage_p95"] > 2.0), ("attachment", q["attachment"] > 0.02)) if bad]
        return "| %s | %s | %.6g | %d | %.2f | %.4f | %.2f | %s |" % (
            name, r["status"], q["inside_fraction"], q["inverted_cells"], q["coverage_p95"], q["attachment"],
            r["seconds"], ", ".join(fails))

    head = ("| %s | status | inside | inverted cells | coverage p95 | attachment | s | fails |\n"
            "|---|---|---:|---:|---:|---:|---:|---|")
    if dec.get("corpus"):
        emit("### Every corpus muscle, default options")
        emit("")
        emit(head % "muscle")
        for r in dec["corpus"]:
            emit(quality_row(os.path.basename(r["muscle"]), r))
        emit("")

    surface = load("decompose-surface.json")
    if surface and surface.get("surface"):
        emit("### Finer surfaces of one muscle")
        emit("")
        emit("`fascicle bench decompose --data ../shared/data --skip-speed --skip-templates --skip-corpus "
             "--surface 1,2,3 --surface-full --json docs/bench/decompose-surface.json`: the muscle of the speed run, "
             "midpoint-subdivided (the same shape, 4 times the triangles a level), decomposed with default options, "
             "the sphere map and placement on the surface simplified to `--map-faces` (default 100000 triangles) and, "
             "beside it, on the whole surface. Turning and ends: the whole check's figures; memory: the bench "
             "process's peak so far.")
        emit("")
        emit("| triangles | mapped on | simplify s | sphere s (with it) | check s | total s | decompose | "
             "segments out | turning deg | ends | peak MiB |")
        emit("|---:|---:|---:|---:|---:|---:|---|---:|---:|---|---:|")
        for r in surface["surface"]:
            q = r["quality"]
            emit("| %d | %d | %.2f | %.2f | %.2f | %.2f | %s | %d | %.1f | %.2f / %.2f | %.0f |" % (
                r["triangles"], r["map_triangles"], r["simplify_seconds"], r["sphere_seconds"], r["check_seconds"],
                r["seconds"], "pass" if q["pass"] else "fail", q["crossing_segments"], r["max_turning_deg"],
                r["ends"][0], r["ends"][1], r["peak_resident_kib_so_far"] / 1024.0))
        emit("")

    templates = load("decompose-templates.json")
    if templates and templates.get("templates"):
        t = templates["templates"]
        emit("### Every template on the LHDL muscles with their landmark files (%d of %d pass)" % (
            sum(1 for r in t if r.get("status") == "ok"), len(t)))
        emit("")
        emit("`fascicle bench decompose --data ../shared/data --skip-speed --skip-corpus --json "
             "docs/bench/decompose-templates.json`; s: the whole decomposition with its tries, one after another.")
        emit("")
        emit(head % "muscle, template")
        for r in t:
            emit(quality_row("%s, %s" % (os.path.basename(r["muscle"]), r["template"]), r))
        emit("")

print("\n".join(lines).rstrip() + "\n", end="")
