#!/usr/bin/python3
"""Side-by-side speed of two builds: runs the micro-benchmarks of two csympnet_bench binaries
in alternation (before, after, before, after, ...) and prints each benchmark's median time
per iteration and the ratio after/before. Alternating spreads the machine's noise over both.

    bench/compare_speed.py --before OLD/csympnet_bench --after build/bin/csympnet_bench \\
        [--filter 'epoch/s[123]/csympnet$'] [--rounds 5]

A ratio above 1 means the after build is slower. With --cli-before/--cli-after it also times
`csympnet fit` (the identification recipe: warm start, AdamW, LM, interval) on generated s1
and s2 data, the same way.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time


def run_bench(binary, flt):
    out = subprocess.run([binary, f"--benchmark_filter={flt}", "--benchmark_format=json",
                          "--benchmark_min_time=0.3"], check=True, capture_output=True, text=True)
    return {b["name"]: b["real_time"] * {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}[b["time_unit"]]
            for b in json.loads(out.stdout)["benchmarks"]}


def time_fit(cli, data, out):
    t0 = time.perf_counter()
    subprocess.run([cli, "fit", data, "--out", out, "-q", "--force"], check=True,
                   capture_output=True)
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", required=True)
    ap.add_argument("--after", required=True)
    ap.add_argument("--filter", default="epoch/(s1|s2|s3|s2-100)/csympnet$")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--cli-before")
    ap.add_argument("--cli-after")
    a = ap.parse_args()
    times = {"before": {}, "after": {}}
    for _ in range(a.rounds):
        for side in ("before", "after"):
            for name, t in run_bench(getattr(a, side), a.filter).items():
                times[side].setdefault(name, []).append(t)
    print(f"{'benchmark':40s} {'before':>12s} {'after':>12s} {'after/before':>12s}")
    for name in times["before"]:
        b, f = statistics.median(times["before"][name]), statistics.median(times["after"][name])
        print(f"{name:40s} {b * 1e6:10.2f}us {f * 1e6:10.2f}us {f / b:12.3f}")
    if a.cli_before and a.cli_after:
        with tempfile.TemporaryDirectory() as tmp:
            for preset in ("s1", "s2"):
                data = os.path.join(tmp, f"{preset}.csv")
                subprocess.run([a.cli_after, "generate", "--preset", preset, "--sigma", "0.001",
                                "--out", data], check=True, capture_output=True)
                fit = {"before": [], "after": []}
                for _ in range(max(1, a.rounds // 2)):
                    for side in ("before", "after"):
                        cli = getattr(a, f"cli_{side}")
                        fit[side].append(time_fit(cli, data, os.path.join(tmp, f"out-{side}")))
                b, f = statistics.median(fit["before"]), statistics.median(fit["after"])
                print(f"{'fit ' + preset + ' (whole command)':40s} {b:11.2f}s {f:11.2f}s {f / b:12.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
