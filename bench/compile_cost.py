#!/usr/bin/python3
"""Compile CPU time (user + sys) of chosen files under three sets of optimisation and debug
flags, one after another, taken from a build directory's compile_commands.json:

    bench/compile_cost.py --build build-asan src/models/g_sympnet.cpp tests/cli/hostile_test.cpp

Compares CMake's RelWithDebInfo default (-O2 -g) with -O2 -g1 and -O1 -g1 (what `make
test-asan` uses, docs/testing.md). With --as-is, each file once with its build's own flags
(two builds' directories, e.g. before and after a change, then compare file by file); --jobs N
compiles N of them at a time (each still timed alone by its own rusage), and a suffix of
".cpp .cxx" takes every file of the build, unity files included. CPU time rather than wall
time, so other jobs on the machine disturb it less.
"""

import argparse
import json
import os
import shlex
import subprocess
import tempfile
from concurrent.futures import ThreadPoolExecutor

VARIANTS = {"-O2 -g": {}, "-O2 -g1": {"-g": "-g1"}, "-O1 -g1": {"-O2": "-O1", "-g": "-g1"}}


def compile_alone(args, cwd):
    """One compile's CPU seconds (user + sys) from its own rusage, so that compiles running
    side by side are each timed alone."""
    proc = subprocess.Popen(args, cwd=cwd, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    if status != 0:
        raise SystemExit(f"compile failed: {' '.join(args)}")
    return usage.ru_utime + usage.ru_stime


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", default="build-asan", help="build directory with compile_commands.json")
    ap.add_argument("--as-is", action="store_true", help="only the build's own flags")
    ap.add_argument("--jobs", type=int, default=1, help="with --as-is: compiles at a time")
    ap.add_argument("files", nargs="+", help="source files (path suffixes)")
    a = ap.parse_args()
    if a.jobs < 1 or (a.jobs > 1 and not a.as_is):
        ap.error("--jobs: expected a count >= 1, and more than 1 only with --as-is")
    variants = {"as built": {}} if a.as_is else VARIANTS
    with open(os.path.join(a.build, "compile_commands.json")) as f:
        commands = json.load(f)
    chosen = [e for e in commands if any(e["file"].endswith(s) for s in a.files)]
    totals = dict.fromkeys(variants, 0.0)
    with tempfile.TemporaryDirectory() as tmp:
        def timed(item):
            i, entry = item
            args = shlex.split(entry["command"])
            args[args.index("-o") + 1] = os.path.join(tmp, f"unit{i}.o")
            return entry["file"], [(name, compile_alone([swap.get(x, x) for x in args], entry["directory"]))
                                   for name, swap in variants.items()]
        with ThreadPoolExecutor(a.jobs) as pool:
            for path, row in pool.map(timed, enumerate(chosen)):
                for name, took in row:
                    totals[name] += took
                print(f"{path}: " + ", ".join(f"{n}: {t:.1f} s" for n, t in row), flush=True)
    print(f"files: {len(chosen)}; total: " + ", ".join(f"{k}: {v:.1f} s" for k, v in totals.items()))


if __name__ == "__main__":
    main()
