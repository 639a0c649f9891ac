#!/usr/bin/env python3
"""How the measured-momenta check (docs/derivations.md, "Momenta computed from the positions")
answers on the identification benchmark's cases: their generated momenta (measured, with their
own noise), and copies whose p columns are computed from the noisy q as a user without a
momentum sensor would (numpy.gradient; a Savitzky-Golay derivative, window 11, cubic).

    /usr/bin/python3 experiments/measured_momenta_study.py BENCH_DIR [--jobs 2]

BENCH_DIR is an identification_benchmark.py output directory (its cases/*/data.csv are read,
nothing there is changed); the copies and csympnet's output go to BENCH_DIR/momenta_study/.
The check is a property of the data, computed before any fit, so each `csympnet fit` here runs
with a token budget (one epoch, one LM iteration, a small core): only the check is read.
Prints, per kind of momenta, how many cases the check failed, passed and found untestable,
with the cases it failed on the given momenta and passed on computed ones."""
import argparse
import concurrent.futures as cf
import json
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from identification_benchmark import computed_momenta  # noqa: E402

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TOKEN_FIT = ["--epochs", "1", "--lm-iterations", "1", "--core", "la:2:2", "-q", "--force"]


def read_case(path):
    with open(path) as f:
        header = f.readline().strip().split(",")
    a = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    d = sum(1 for h in header if h.startswith("q"))
    files = [(a[a[:, 0] == j, 1], a[a[:, 0] == j, 2:]) for j in np.unique(a[:, 0])]
    return files, d


def write_case(path, files, d):
    names = [f"q{i + 1}" for i in range(d)] + [f"p{i + 1}" for i in range(d)]
    with open(path, "w") as f:
        f.write("traj,t," + ",".join(names) + "\n")
        for j, (t, z) in enumerate(files):
            for k in range(len(t)):
                f.write(f"{j}," + ",".join(repr(float(x)) for x in [t[k], *z[k]]) + "\n")


def check_of(exe, data, out):
    subprocess.run([exe, "fit", data, "--out", out, *TOKEN_FIT], stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, check=False)
    try:
        with open(os.path.join(out, "report.json")) as f:
            rep = json.load(f)
    except (OSError, ValueError):
        return "no report"
    c = next((c for c in rep.get("checks", []) if c["name"] == "measured_momenta"), None)
    if c is None:
        return "no check"
    return "untestable" if not c["applicable"] else ("passed" if c["passed"] else "failed")


def run(case_dir, work, exe):
    files, d = read_case(os.path.join(case_dir, "data.csv"))
    name = os.path.basename(case_dir)
    out = {}
    for how in ("given", "gradient", "savgol"):
        data = os.path.join(work, f"{name}-{how}.csv")
        write_case(data, files if how == "given" else computed_momenta(files, d, how), d)
        out[how] = check_of(exe, data, os.path.join(work, f"{name}-{how}"))
    return name, out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("bench_dir")
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--csympnet", default=os.path.join(REPO, "build", "bin", "csympnet"))
    a = ap.parse_args()
    root = os.path.join(a.bench_dir, "cases")
    cases = sorted(os.path.join(root, c) for c in os.listdir(root)
                   if os.path.isfile(os.path.join(root, c, "data.csv")))  # not generated: none
    work = os.path.join(a.bench_dir, "momenta_study")
    os.makedirs(work, exist_ok=True)
    with cf.ThreadPoolExecutor(max_workers=a.jobs) as pool:
        results = dict(pool.map(lambda c: run(c, work, a.csympnet), cases))
    for how in ("given", "gradient", "savgol"):
        counts = {}
        for r in results.values():
            counts[r[how]] = counts.get(r[how], 0) + 1
        print(f"{how:9s} " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    for name, r in sorted(results.items()):
        if r["given"] == "failed" or "passed" in (r["gradient"], r["savgol"]):
            print(f"  {name}: given {r['given']}, gradient {r['gradient']}, savgol {r['savgol']}")
    with open(os.path.join(work, "results.json"), "w") as f:
        json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
