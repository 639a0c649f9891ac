#!/usr/bin/env python3
"""Coverage of the driven route's intervals over many records of a driven linear oscillator.

Each record is the oscillator of the driven tests, q'' + gamma q' + omega^2 q = b u(t) with
gamma = 0.1, omega = 2, b = 1.5, u a random-phase multisine of 8 frequencies (0.3 to 3.45 rad
per time unit), integrated by RK4 at 20 steps per sample (u evaluated where RK4 asks: a smooth
input, not a first-order hold), N positions at step H with Gaussian noise of NOISE times their
spread. Seed s draws the phases and the noise (numpy's default_rng(s): the generator of
python/tests/test_identify_inputs.py). Each record is fitted by `csympnet fit` (positions and
the input column), and the report's gamma_hat, its 95% interval, B and its interval are
compared with the truth. Also the change of gamma_hat when the inputs' curvature between
samples is folded in (choices.driven.input_hold), and the interval the independent segments
would give (choices.driven.segment_fit_interval).

Usage:
    /usr/bin/python3 experiments/driven_linked_coverage.py --csympnet build/bin/csympnet \
        --out DIR [--first 100] [--records 40] [--n 1000] [--h 0.05] [--noise 0.005]

Writes DIR/results.json (per record: seed, estimates, intervals) and prints the coverage of
gamma and b, the median widths, and the mean error of gamma_hat beside its standard error.
"""
import argparse
import json
import os
import subprocess

import numpy as np

GAMMA, OMEGA, GAIN = 0.1, 2.0, 1.5


def record(n, h, noise, seed):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * h
    freq = 0.3 + 0.45 * np.arange(8)
    phase = rng.uniform(0.0, 2.0 * np.pi, 8)

    def u(tt):
        return np.sin(freq * tt + phase).sum() / np.sqrt(8.0)

    def field(z, tt):
        return np.array([z[1], -OMEGA**2 * z[0] - GAMMA * z[1] + GAIN * u(tt)])

    z, q, dt = np.array([0.3, 0.0]), np.empty(n), h / 20
    for k in range(n):
        q[k] = z[0]
        for s in range(20):
            ts = t[k] + s * dt
            k1 = field(z, ts)
            k2 = field(z + dt / 2 * k1, ts + dt / 2)
            k3 = field(z + dt / 2 * k2, ts + dt / 2)
            k4 = field(z + dt * k3, ts + dt)
            z = z + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    q += noise * q.std() * rng.normal(size=n)
    return t, q, np.array([u(tt) for tt in t])


def fit_one(exe, out, seed, args):
    t, q, u = record(args.n, args.h, args.noise, seed)
    d = os.path.join(out, f"r{seed}")
    os.makedirs(d, exist_ok=True)
    path = os.path.join(d, "record.csv")
    np.savetxt(path, np.c_[t, q, u], delimiter=",", header="t,q1,u1", comments="")
    subprocess.run([exe, "fit", path, "--out", os.path.join(d, "fit"), "-q", "--no-figures",
                    "--force"], check=True, capture_output=True)
    with open(os.path.join(d, "fit", "report.json")) as f:
        r = json.load(f)
    drv = r["choices"]["driven"]
    seg = drv.get("segment_fit_interval") or {}
    return {"seed": seed, "gamma_hat": r["gamma_hat"], "low": r.get("gamma_ci_low"),
            "high": r.get("gamma_ci_high"), "verdict": r["verdict"],
            "b": r["input"]["B"][0][0], "b_low": r["input"]["B_ci_low"][0][0],
            "b_high": r["input"]["B_ci_high"][0][0],
            "hold_change": drv.get("input_hold", {}).get("gamma_change"),
            "segments_low": seg.get("low"), "segments_high": seg.get("high")}


def summary(rows):
    ok = [r for r in rows if r["low"] is not None]
    cov = sum(r["low"] <= GAMMA <= r["high"] for r in ok)
    covb = sum(r["b_low"] <= GAIN <= r["b_high"] for r in rows)
    width = np.median([r["high"] - r["low"] for r in ok]) if ok else float("nan")
    seg = [r["segments_high"] - r["segments_low"] for r in rows if r["segments_low"] is not None]
    err = np.array([r["gamma_hat"] - GAMMA for r in rows])
    sd = err.std(ddof=1) if len(err) > 1 else float("nan")
    print(f"records {len(rows)}, with an interval {len(ok)}, identified "
          f"{sum(r['verdict'] == 'identified' for r in rows)}")
    print(f"gamma covered {cov}/{len(ok)}, b covered {covb}/{len(rows)}")
    print(f"median width of gamma's interval {width:.3g}; the independent segments' "
          f"{np.median(seg) if seg else float('nan'):.3g}")
    print(f"gamma_hat - gamma: mean {err.mean():.3g}, sd {sd:.3g} "
          f"(standard error of the mean {sd / np.sqrt(len(err)):.3g})")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--csympnet", default="build/bin/csympnet")
    ap.add_argument("--out", required=True)
    ap.add_argument("--first", type=int, default=100)
    ap.add_argument("--records", type=int, default=40)
    ap.add_argument("--n", type=int, default=1000)
    ap.add_argument("--h", type=float, default=0.05)
    ap.add_argument("--noise", type=float, default=0.005)
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    rows = []
    for seed in range(args.first, args.first + args.records):
        rows.append(fit_one(os.path.abspath(args.csympnet), args.out, seed, args))
        r = rows[-1]
        print(f"seed {seed}: gamma_hat {r['gamma_hat']:.6g} [{r['low']}, {r['high']}], "
              f"b {r['b']:.6g} [{r['b_low']:.6g}, {r['b_high']:.6g}] {r['verdict']}",
              flush=True)
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump({"args": vars(args), "records": rows}, f, indent=1)
    summary(rows)


if __name__ == "__main__":
    main()
