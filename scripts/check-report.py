#!/usr/bin/env python3
"""Checks that a `softshadow report` output directory is complete and well-formed (what CI runs
after `softshadow report --quick`): results.csv/json parse and agree, every registered estimator
and fixture appears, every scored run has finite metrics and no non-finite V, every plot and grid
image referenced by index.md exists.
    scripts/check-report.py OUT_DIR [--expect-backends cpu,gpu]
"""
import csv, json, math, os, re, sys

out = sys.argv[1]
backends = {"cpu"}
if "--expect-backends" in sys.argv:
    backends = set(sys.argv[sys.argv.index("--expect-backends") + 1].split(","))
fail = []
rows = list(csv.DictReader(open(os.path.join(out, "results.csv"))))
js = json.load(open(os.path.join(out, "results.json")))
if len(rows) != len(js["runs"]):
    fail.append(f"csv has {len(rows)} rows, json {len(js['runs'])}")
algos = {r["algo"] for r in rows}
fixtures = {r["fixture"] for r in rows}
want = {"hard", "pcf", "pcss", "multi-sample", "backprojection", "accumulation", "packet-hsm", "deep-shadow"}
if not want <= algos:
    fail.append(f"missing estimators: {sorted(want - algos)}")
if {r["backend"] for r in rows} != backends:
    fail.append(f"backends {sorted({r['backend'] for r in rows})}, expected {sorted(backends)}")
ok = 0
for r in rows:
    if r["status"] == "ok":
        ok += 1
        for k in ("build_ms", "estimate_ms", "frame_ms", "rmse", "mae", "p99", "frac_gt_0_1"):
            v = float(r[k])
            if not math.isfinite(v) or v < 0:
                fail.append(f"{r['fixture']} {r['algo']} {r['backend']} {r['setting']}: {k} = {r[k]}")
        if float(r["rmse"]) > 1 or int(r["nonfinite"]) != 0:
            fail.append(f"{r['fixture']} {r['algo']} {r['backend']}: rmse {r['rmse']} nonfinite {r['nonfinite']}")
    elif not r["status"].startswith("rejected: "):
        fail.append(f"bad status {r['status']!r}")
if ok < 0.8 * len(rows):
    fail.append(f"only {ok} of {len(rows)} runs scored")
flick = list(csv.DictReader(open(os.path.join(out, "flicker.csv"))))
if not flick or {f["fit"] for f in flick} != {"receivers", "scene", "stable"}:
    fail.append("flicker.csv lacks the three fit modes")
md = open(os.path.join(out, "index.md")).read()
for fx in fixtures:
    if f"## {fx}" not in md:
        fail.append(f"index.md has no section for {fx}")
for ref in re.findall(r"\]\(([^)]+\.(?:svg|png))\)", md):
    p = os.path.join(out, ref)
    if not os.path.exists(p) or os.path.getsize(p) == 0:
        fail.append(f"index.md references missing {ref}")
for svg in [f for f in os.listdir(out) if f.endswith(".svg")]:
    s = open(os.path.join(out, svg)).read()
    if "<svg" not in s or "</svg>" not in s:
        fail.append(f"{svg} is not an SVG")
# Each fixture: the time and the memory plot, each with a legend entry per backend present.
backends_present = {r["backend"] for r in rows if r["status"] == "ok"}
for fx in fixtures:
    for kind in ("plot", "memory"):
        p = os.path.join(out, f"{kind}-{fx}.svg")
        if not os.path.exists(p):
            fail.append(f"{kind}-{fx}.svg missing")
            continue
        s = open(p).read()
        for b in backends_present:
            if not re.search(r">\s*%s\s*<" % b.upper(), s):
                fail.append(f"{kind}-{fx}.svg has no {b.upper()} legend entry")
for section in ("## Summary", "## Each seed algorithm", "## Flicker per fit mode"):
    if section not in md:
        fail.append(f"index.md lacks {section!r}")
if fail:
    print("report check FAILED:\n  " + "\n  ".join(fail[:40]))
    sys.exit(1)
print(f"report check: {len(rows)} runs ({ok} scored), {len(fixtures)} fixtures, {len(algos)} estimators, {len(flick)} flicker rows: ok")
