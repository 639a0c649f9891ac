#!/usr/bin/python3
"""Compile CPU time (user + sys) of chosen files under three sets of optimisation and debug
flags, one after another, taken from a build directory's compile_commands.json:

    bench/compile_cost.py --build build-asan src/models/g_sympnet.cpp tests/cli/hostile_test.cpp

Compares CMake's RelWithDebInfo default (-O2 -g) with -O2 -g1 and -O1 -g1 (what `make
test-asan` uses, docs/testing.md). With --as-is, each file once with its build's own flags
(two builds' directories, e.g. before and after a change, then compare file by file). CPU
time rather than wall time, so other jobs on the machine disturb it less.
"""

import argparse
import json
import os
import resource
import shlex
import subprocess
import tempfile

VARIANTS = {"-O2 -g": {}, "-O2 -g1": {"-g": "-g1"}, "-O1 -g1": {"-O2": "-O1", "-g": "-g1"}}


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", default="build-asan", help="build directory with compile_commands.json")
    ap.add_argument("--as-is", action="store_true", help="only the build's own flags")
    ap.add_argument("files", nargs="+", help="source files (path suffixes)")
    a = ap.parse_args()
    variants = {"as built": {}} if a.as_is else VARIANTS
    with open(os.path.join(a.build, "compile_commands.json")) as f:
        commands = json.load(f)
    totals = dict.fromkeys(variants, 0.0)
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "unit.o")
        for entry in commands:
            if not any(entry["file"].endswith(s) for s in a.files):
                continue
            args = shlex.split(entry["command"])
            args[args.index("-o") + 1] = out
            row = []
            for name, swap in variants.items():
                start = children_cpu()
                subprocess.run([swap.get(x, x) for x in args], cwd=entry["directory"], check=True,
                               stderr=subprocess.DEVNULL)
                took = children_cpu() - start
                totals[name] += took
                row.append(f"{name}: {took:.1f} s")
            print(f"{entry['file']}: " + ", ".join(row), flush=True)
    print("total: " + ", ".join(f"{k}: {v:.1f} s" for k, v in totals.items()))


if __name__ == "__main__":
    main()
