#!/usr/bin/env python3
"""Checks a `softshadow report` output directory (what CI runs after `softshadow report --quick`):
results.csv/json parse and agree, every registered estimator and fixture appears, every scored
run has finite metrics and no non-finite V, every plot and grid image referenced by index.md
exists, every run of a method that casts opaque shadows on a fixture with semi-transparent
meshes carries its `opaque_casters` warning, and, with --expect, every row against the committed expectation: a row missing, a row
the expectation does not list, a row that newly fails, or a row whose RMSE rises by more than
max(0.002, 10%) fails the check.

    scripts/check-report.py OUT_DIR [--expect-backends cpu,gpu] [--expect EXPECTED.csv]
    scripts/check-report.py --write-expect EXPECTED.csv OUT_DIR      # regenerate (commit it with its reason)
    scripts/check-report.py --self-test OUT_DIR [...]                # the checker rejects a raised RMSE

The expectation (scripts/expected/report-quick.csv) holds, per fixture, method, setting and
backend, the status and the RMSE.
"""
import csv, json, math, os, re, sys, tomllib

KEY = ("fixture", "algo", "setting", "backend")
# A row's RMSE may rise by this much before the check fails: max(ABS, REL * expected).
ABS, REL = 0.002, 0.10


def status_class(status):
    return "ok" if status == "ok" else "rejected"


def against_expectation(rows, expected):
    """The rows' failures against the expectation's rows (both lists of dicts)."""
    fail = []
    want = {tuple(e[k] for k in KEY): e for e in expected}
    got = {}
    for r in rows:
        k = tuple(r[c] for c in KEY)
        if k in got:
            fail.append(f"{' '.join(k)}: twice in results.csv")
        got[k] = r
    for k, e in want.items():
        r = got.get(k)
        name = " ".join(k)
        if r is None:
            fail.append(f"{name}: missing (expected {e['status']}, RMSE {e['rmse']})")
            continue
        if status_class(e["status"]) == "ok" and r["status"] != "ok":
            fail.append(f"{name}: newly fails: {r['status']!r}")
            continue
        if status_class(e["status"]) != "ok" and r["status"] == "ok":
            fail.append(f"{name}: now scored (RMSE {r['rmse']}), expected {e['status']!r}: regenerate the expectation")
            continue
        if r["status"] == "ok":
            was, now = float(e["rmse"]), float(r["rmse"])
            if not now <= was + max(ABS, REL * was):
                fail.append(f"{name}: RMSE {now:.5f}, expected {was:.5f} (+{now - was:.5f}, allowed +{max(ABS, REL * was):.5f})")
    for k in got:
        if k not in want:
            fail.append(f"{' '.join(k)}: not in the expectation: regenerate it (scripts/check-report.py --write-expect)")
    return fail


# Methods that treat every caster as opaque (the others model opacity) and so must warn.
OPAQUE_ONLY = {"hard", "pcf", "pcss", "multi-sample", "accumulation"}


def semi_transparent_fixtures(fixtures_dir="fixtures"):
    """Fixtures (NAME/NAME.toml) with a mesh of opacity below 1."""
    out = set()
    for name in sorted(os.listdir(fixtures_dir)) if os.path.isdir(fixtures_dir) else []:
        p = os.path.join(fixtures_dir, name, name + ".toml")
        if os.path.exists(p):
            meshes = tomllib.load(open(p, "rb")).get("mesh", [])
            if any(float(m.get("opacity", 1.0)) < 1.0 for m in meshes):
                out.add(name)
    return out


def read_rows(out):
    return list(csv.DictReader(open(os.path.join(out, "results.csv"))))


def check(out, backends, expected):
    """Every failure of the report in `out` (an empty list when it passes)."""
    rows = read_rows(out)
    fail = []
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
    semi = semi_transparent_fixtures() & fixtures
    for r in rows:
        if r["fixture"] in semi and r["algo"] in OPAQUE_ONLY and r["status"] == "ok":
            if "opaque_casters=" not in r.get("warnings", ""):
                fail.append(f"{r['fixture']} {r['algo']} {r['backend']} {r['setting']}: no opaque_casters warning ({r.get('warnings')!r})")
    if not semi:
        fail.append("no fixture with semi-transparent meshes: the opaque-casters check checked nothing")
    if expected is not None:
        fail.extend(against_expectation(rows, expected))
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
        return fail
    print(f"report check: {len(rows)} runs ({ok} scored), {len(fixtures)} fixtures, {len(algos)} estimators, {len(flick)} flicker rows: ok")
    return []


def write_expect(path, out):
    rows = read_rows(out)
    with open(path, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(list(KEY) + ["status", "rmse"])
        for r in sorted(rows, key=lambda r: tuple(r[c] for c in KEY)):
            w.writerow([r[c] for c in KEY] + [r["status"], r["rmse"] if r["status"] == "ok" else ""])
    print(f"wrote {len(rows)} rows to {path}")


def self_test(out, backends, expected):
    """The checker must reject a copy of the report with one scored row's RMSE raised by 0.05,
    one with a scored row turned into a failure, one with a row removed, and one with an
    opaque-caster run's warning dropped."""
    import shutil, tempfile
    if expected is None:
        return ["--self-test needs --expect"]
    rows = read_rows(out)
    scored = [i for i, r in enumerate(rows) if r["status"] == "ok"]
    if not scored:
        return ["--self-test: no scored row to alter"]
    i = scored[len(scored) // 2]
    fields = list(rows[0].keys())

    def altered(edit):
        tmp = tempfile.mkdtemp()
        shutil.rmtree(tmp)
        shutil.copytree(out, tmp)
        rs = [dict(r) for r in rows]
        rs = edit(rs)
        with open(os.path.join(tmp, "results.csv"), "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=fields, lineterminator="\n")
            w.writeheader()
            w.writerows(rs)
        js = json.load(open(os.path.join(tmp, "results.json")))
        js["runs"] = js["runs"][: len(rs)]
        json.dump(js, open(os.path.join(tmp, "results.json"), "w"))
        fails = check(tmp, backends, expected)
        shutil.rmtree(tmp)
        return fails

    def raise_rmse(rs):
        rs[i]["rmse"] = str(float(rs[i]["rmse"]) + 0.05)
        return rs

    def make_fail(rs):
        rs[i]["status"] = "rejected: self-test"
        return rs

    def drop(rs):
        return rs[:i] + rs[i + 1:]

    bad = []
    name = " ".join(rows[i][c] for c in KEY)
    for what, edit in (("RMSE raised by 0.05", raise_rmse), ("a newly failing row", make_fail), ("a removed row", drop)):
        fails = check_quiet(altered, edit)
        if not any(name in f for f in fails):
            bad.append(f"self-test: the checker accepted {what} ({name}); it reported {fails[:3]}")
        else:
            print(f"self-test: {what} ({name}) rejected: {[f for f in fails if name in f][0]}")
    # A semi-transparent fixture's opaque-caster run with its warning dropped.
    semi = semi_transparent_fixtures()
    warned = [j for j, r in enumerate(rows) if r["fixture"] in semi and r["algo"] in OPAQUE_ONLY and r["status"] == "ok"]
    if not warned:
        return bad + ["--self-test: no opaque-caster run on a semi-transparent fixture to alter"]
    j = warned[0]
    wname = f"{rows[j]['fixture']} {rows[j]['algo']} {rows[j]['backend']} {rows[j]['setting']}"

    def unwarn(rs):
        rs[j]["warnings"] = ""
        return rs

    fails = check_quiet(altered, unwarn)
    if not any(wname in f and "opaque_casters" in f for f in fails):
        bad.append(f"self-test: the checker accepted a dropped opaque_casters warning ({wname})")
    else:
        print(f"self-test: a dropped opaque_casters warning ({wname}) rejected")
    return bad


def check_quiet(altered, edit):
    import contextlib, io
    with contextlib.redirect_stdout(io.StringIO()):
        return altered(edit)


def main(argv):
    backends, expected, out = {"cpu"}, None, None
    mode = "check"
    it = iter(argv)
    for a in it:
        if a == "--expect-backends":
            backends = set(next(it).split(","))
        elif a == "--expect":
            expected = list(csv.DictReader(open(next(it))))
        elif a == "--write-expect":
            mode, target = "write", next(it)
        elif a == "--self-test":
            mode = "self-test"
        else:
            out = a
    if out is None:
        print(__doc__)
        return 2
    if mode == "write":
        write_expect(target, out)
        return 0
    fail = self_test(out, backends, expected) if mode == "self-test" else check(out, backends, expected)
    if fail:
        print("report check FAILED:\n  " + "\n  ".join(fail[:40]))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
