"""What the scripts/check-*.py checkers share: the JSON lines a program printed, the methods of
the frame API every such run must list, and the verdict line with its exit status. A checker
imports it as `checklib` (Python puts the script's own folder on the module path)."""
import json
import sys

# The eight methods of the frame API (softshadow::FRAME_ALGOS).
FRAME_METHODS = {"hard", "pcf", "pcss", "multi-sample", "backprojection", "accumulation", "deep-shadow", "packet-hsm"}


def json_rows(stream=sys.stdin):
    """Every line of `stream` that is a JSON object, parsed (cargo's and other lines skipped)."""
    return [json.loads(l) for l in stream if l.strip().startswith("{")]


def missing_methods(rows, noun):
    """The failure line for frame-API methods no row names (`noun`: what a row is), or none."""
    missing = FRAME_METHODS - {r["algo"] for r in rows}
    return ["missing %s: %s" % (noun, sorted(missing))] if missing else []


def finish(check, bad, ok):
    """Prints `check`'s verdict: the failures `bad` (exit status 1), or `ok` and status 0."""
    if bad:
        print("%s failed:\n  %s" % (check, "\n  ".join(bad)))
        sys.exit(1)
    print("%s: %s: ok" % (check, ok))
