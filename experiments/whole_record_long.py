#!/usr/bin/env python3
"""A 10^5-sample pendulum record with measured velocity, fitted on windows and over the whole
record, side by side (docs/identification.md, "Records with momenta: the whole record").

    /usr/bin/python3 experiments/whole_record_long.py --out DIR [--csympnet PATH] [--samples N]

The record: theta'' = -omega^2 sin(theta) - gamma theta', omega = 2 pi, gamma = 0.01, from
0.5 rad at rest, 100 samples per second for N / 100 s (RK4 with 10 substeps per sample), the
amplitude decaying to about 0.003 rad at N = 10^5; Gaussian noise 5e-4 rad on the angle and
5e-4 omega rad/s on the velocity (seed 5). Each fit's gamma_hat, interval and CPU seconds
(wait4 of the child) are printed and written to DIR/summary.json.
"""
import argparse
import json
import os
import resource
import subprocess
import sys

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def record(n):
    w, g, h, sub = 2 * np.pi, 0.01, 0.01, 10

    def f(z):
        return np.array([z[1], -w * w * np.sin(z[0]) - g * z[1]])

    z, out, hh = np.array([0.5, 0.0]), np.empty((n, 2)), h / sub
    for k in range(n):
        out[k] = z
        for _ in range(sub):
            k1 = f(z)
            k2 = f(z + hh / 2 * k1)
            k3 = f(z + hh / 2 * k2)
            k4 = f(z + hh * k3)
            z = z + hh / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    rng = np.random.default_rng(5)
    out[:, 0] += 5e-4 * rng.standard_normal(n)
    out[:, 1] += 5e-4 * w * rng.standard_normal(n)
    return h * np.arange(n), out, g


def fit(exe, data, out, mode):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run([exe, "fit", data, "--out", out, "--force", "--quiet", "--no-figures",
                           "--record-fit", mode], capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    rep = json.load(open(os.path.join(out, "report.json")))
    iv = rep.get("interval") or {}
    return {"mode": mode, "exit": proc.returncode, "gamma_hat": rep.get("gamma_hat"),
            "low": iv.get("low"), "high": iv.get("high"), "cpu_seconds": cpu}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--csympnet", default=os.path.join(REPO, "build", "bin", "csympnet"))
    ap.add_argument("--samples", type=int, default=100000)
    args = ap.parse_args()
    if os.path.exists(args.out) and os.listdir(args.out):
        sys.exit(f"{args.out}: exists and is not empty; expected a new directory")
    os.makedirs(args.out, exist_ok=True)
    t, z, gamma = record(args.samples)
    data = os.path.join(args.out, "pendulum_1e5.csv")
    np.savetxt(data, np.c_[t, z], delimiter=",", header="t,q1,p1", comments="")
    rows = []
    for mode in ("windows", "whole"):
        r = fit(args.csympnet, data, os.path.join(args.out, mode), mode)
        r["covers"] = r["low"] is not None and r["low"] <= gamma <= r["high"]
        rows.append(r)
        print(f"{mode:8s} gamma_hat {r['gamma_hat']:.7g} [{r['low']:.7g}, {r['high']:.7g}] "
              f"(true {gamma}) {'covers' if r['covers'] else 'misses'}, "
              f"{r['cpu_seconds']:.1f} CPU s", flush=True)
    json.dump({"samples": args.samples, "gamma": gamma, "fits": rows},
              open(os.path.join(args.out, "summary.json"), "w"), indent=1)


if __name__ == "__main__":
    main()
