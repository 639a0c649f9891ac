#!/usr/bin/python3
"""Checks that an optimisation did not move any result: runs `csympnet run` with two binaries
(before and after) on the same runs and compares report.json (every field but wall times) and
model.json (θ to the last digit written, 17 significant) exactly.

    bench/compare_reports.py --before OLD/csympnet --after build/bin/csympnet [--quick]
                             [--after-threads 2]

The default list covers every model on s1 and the map models (whose training path the
optimisations touch) on s2, s3 and s2-100 with short budgets; s1 CSympNet-ID runs its full
default budget (the issue's reference check). Exit status 1 if anything differs.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

# (preset, model, epochs or None for the preset's default budget)
RUNS = [
    ("s1", "csympnet", None),
    ("s1", "sympnet", 3000),
    ("s1", "map", 1000),
    ("s1", "ode", 1000),
    ("s1", "dhnn", 500),
    ("s1", "dhnn2", 500),
    ("s1", "phnn", 500),
    ("s1", "phnn2", 500),
    ("s2", "csympnet", 2000),
    ("s2", "sympnet", 1000),
    ("s3", "csympnet", 2000),
    ("s3", "sympnet", 500),
    ("s2-100", "csympnet", 30),
    ("s2", "map", 300),
    ("s2", "dhnn", 100),
    ("s3", "phnn", 100),
]
QUICK = [("s1", "csympnet", None), ("s2", "csympnet", 300), ("s3", "csympnet", 300),
         ("s2-100", "csympnet", 10)]


def is_timing(key):
    # Wall times, and the thread count a run was given (results do not depend on it).
    return key.endswith("seconds") or key == "train_threads"


def strip_timing(value):
    if isinstance(value, dict):
        return {k: strip_timing(v) for k, v in value.items() if not is_timing(k)}
    if isinstance(value, list):
        return [strip_timing(v) for v in value]
    return value


def run(binary, preset, model, epochs, out, extra=()):
    cmd = ["nice", "-n", "19", binary, "run", "--preset", preset, "--model", model, "--seed", "42",
           "--out", out, "-q", *extra]
    if epochs is not None:
        cmd += ["--epochs", str(epochs)]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    with open(os.path.join(out, "report.json")) as f:
        report = strip_timing(json.load(f))
    with open(os.path.join(out, "model.json")) as f:
        model_file = f.read()
    return report, model_file


def differences(a, b, path=""):
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            yield from differences(a.get(k), b.get(k), f"{path}.{k}" if path else k)
    elif a != b:
        yield f"{path}: {a!r} != {b!r}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="csympnet binary built from the old code")
    ap.add_argument("--after", required=True, help="csympnet binary built from the new code")
    ap.add_argument("--quick", action="store_true", help="CSympNet-ID on the four presets only")
    ap.add_argument("--after-threads", type=int, default=1,
                    help="run the new binary with --threads N (N > 1: also checks that the "
                    "threaded epochs give the serial bits)")
    args = ap.parse_args()
    bad = 0
    with tempfile.TemporaryDirectory() as tmp:
        for preset, model, epochs in QUICK if args.quick else RUNS:
            label = f"{preset}/{model} ({'default' if epochs is None else epochs} epochs)"
            before = run(args.before, preset, model, epochs, os.path.join(tmp, "a", preset, model))
            extra = ["--threads", str(args.after_threads)] if args.after_threads > 1 else []
            after = run(args.after, preset, model, epochs, os.path.join(tmp, "b", preset, model),
                        extra)
            diffs = list(differences(before[0], after[0]))
            if before[1] != after[1]:
                diffs.append("model.json: θ differs")
            print(f"{label:32s} {'identical' if not diffs else 'DIFFERENT'}", flush=True)
            for d in diffs[:8]:
                print("    " + d)
            bad += bool(diffs)
    print("all reports bit-identical (timing fields aside)" if not bad
          else f"{bad} run(s) differ")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
