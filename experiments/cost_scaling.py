#!/usr/bin/env python3
"""What a fit costs against the record's length: `csympnet fit` beside the parametric oracle
on one damped oscillator record of N samples, N from 10^3 up (docs/benchmarks.md, "A fit's
cost against the record's length").

    /usr/bin/python3 experiments/cost_scaling.py --out DIR [--csympnet PATH]
        [--lengths 1000,3162,10000,31623,100000] [--observed momenta,positions] [--seed 1]
        [--figure]

The record: q'' = -omega^2 q - gamma q', omega = 2 pi / (30 h) (30 samples a period), h = 0.05,
from q = 1 at rest, one trajectory of N samples (the exact solution), gamma = 4 / (N h) so that
every record decays by the same factor e^-2 whatever its length; Gaussian noise of 0.5% of each
column's spread (q, and p = q' with momenta). Every record of one length is drawn from the seed
and the length alone.

The oracle is the true form fitted by least squares (scipy.optimize.least_squares, the exact
solution in closed form, omega, gamma, q0 and v0 unknown, started at the truth with omega and
gamma times exp(0.2 z)); gamma +- 1.96 Gauss-Newton standard errors. Its cost is the Python
process time of the fit; csympnet's is the CPU seconds of the `fit` child (wait4). Both are
written per length with the estimate, its interval and whether it covers, to DIR/results.json
and DIR/summary.md, with the log-log slope of CPU seconds against N over N >= 10^4 (and the
figure DIR/cost_scaling.png with --figure). Ctrl-C stops the child and writes what is done.
"""
import argparse
import json
import math
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from idbench.common import STOP, Interrupted  # noqa: E402
from idbench.peers.csympnet import CHILDREN, CHILDREN_LOCK, kill_group, run_csympnet  # noqa: E402

H = 0.05
SAMPLES_PER_PERIOD = 30
NOISE = 0.005


def install_stop_handlers():
    """SIGINT or SIGTERM: the running fit's process group is killed and the loop stops (the
    rows done so far are written)"""
    import signal

    def on_signal(signum, frame):
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        STOP.set()
        with CHILDREN_LOCK:
            kids = list(CHILDREN)
        for c in kids:
            kill_group(c, signal.SIGKILL)
        raise Interrupted()
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)


def truth_for(n):
    omega = 2 * math.pi / (SAMPLES_PER_PERIOD * H)
    return {"omega": omega, "gamma": 4.0 / (n * H), "q0": 1.0, "v0": 0.0, "h": H, "n": n}


def exact(t, omega, gamma, q0, v0):
    """q(t) and q'(t) of q'' = -omega^2 q - gamma q' (underdamped) from (q0, v0)"""
    wd = math.sqrt(max(omega * omega - 0.25 * gamma * gamma, 1e-300))
    a, b = q0, (v0 + 0.5 * gamma * q0) / wd
    e = np.exp(-0.5 * gamma * t)
    c, s = np.cos(wd * t), np.sin(wd * t)
    q = e * (a * c + b * s)
    v = e * (-0.5 * gamma * (a * c + b * s) + wd * (-a * s + b * c))
    return q, v


def record(n, seed, momenta):
    tr = truth_for(n)
    t = np.arange(n) * H
    q, v = exact(t, tr["omega"], tr["gamma"], tr["q0"], tr["v0"])
    rng = np.random.default_rng([seed, n])
    qn = q + NOISE * q.std() * rng.standard_normal(n)
    vn = v + NOISE * v.std() * rng.standard_normal(n)
    return t, qn, (vn if momenta else None), tr


def write_csv(path, t, q, p):
    cols = np.column_stack([t, q] + ([] if p is None else [p]))
    header = "t,q1" + ("" if p is None else ",p1")
    np.savetxt(path, cols, delimiter=",", header=header, comments="", fmt="%.17g")


def oracle(t, q, p, tr, seed):
    from scipy.optimize import least_squares
    rng = np.random.default_rng([seed, tr["n"], 1])
    z = np.exp(0.2 * np.clip(rng.standard_normal(2), -2, 2))
    x0 = np.array([tr["omega"] * z[0], tr["gamma"] * z[1], q[0],
                   p[0] if p is not None else (q[1] - q[0]) / H])
    sq, sp = q.std(), (p.std() if p is not None else None)

    def residuals(x):
        qm, vm = exact(t, *x)
        r = [(qm - q) / sq]
        if p is not None:
            r.append((vm - p) / sp)
        return np.concatenate(r)

    # growing prefixes, the first tenth (at most 10^4 samples) and then ten times longer each
    # time, then the whole record: a frequency started 2e-2 off drifts a long record's phase by
    # many periods (at 10^6 samples the first tenth alone, 3,333 periods, left the fit in
    # another minimum). gamma >= 0: a trial gamma below 0 overflows e^{-gamma t / 2} over a long
    # record.
    fit = None
    m, stages = max(min(len(t) // 10, 10000), 50), []
    while m < len(t):
        stages.append(m)
        m *= 10
    stages.append(len(t))
    lower = [0.0, 0.0, -np.inf, -np.inf]
    for m in stages:
        tt, qq, pp = t[:m], q[:m], (p[:m] if p is not None else None)

        def part(x, tt=tt, qq=qq, pp=pp):
            qm, vm = exact(tt, *x)
            r = [(qm - qq) / sq]
            if pp is not None:
                r.append((vm - pp) / sp)
            return np.concatenate(r)

        fit = least_squares(part, x0 if fit is None else fit.x, method="trf", x_scale="jac",
                            bounds=(lower, np.inf))
    r = residuals(fit.x)
    s2 = float(r @ r) / max(r.size - 4, 1)
    cov = s2 * np.linalg.inv(fit.jac.T @ fit.jac)
    se = math.sqrt(max(cov[1, 1], 0.0))
    g = float(fit.x[1])
    return {"gamma_hat": g, "ci_low": g - 1.959963984540054 * se,
            "ci_high": g + 1.959963984540054 * se, "nfev": int(fit.nfev)}


def slope(rows, key):
    pts = [(math.log(r["n"]), math.log(r[key])) for r in rows
           if r["n"] >= 10000 and r.get(key) and r[key] > 0]
    if len(pts) < 2:
        return None
    x, y = np.array(pts).T
    return float(np.polyfit(x, y, 1)[0])


def summarize(rows, args):
    lines = ["# A fit's cost against the record's length", "",
             f"seed {args.seed}, csympnet `{args.csympnet}`; CPU seconds (csympnet: wait4 of "
             "`fit`; oracle: process time of its least squares)", ""]
    for obs in args.observed:
        sub = [r for r in rows if r["observed"] == obs]
        if not sub:
            continue
        lines += [f"## {obs}", "",
                  "| N | csympnet CPU s | oracle CPU s | ratio | csympnet gamma covered | "
                  "oracle covered | csympnet width / oracle's | csympnet status |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in sub:
            c, o = r["csympnet"], r["oracle"]
            ratio = (c["cpu_seconds"] / o["cpu_seconds"]
                     if c.get("cpu_seconds") and o.get("cpu_seconds") else None)
            width = ((c["ci_high"] - c["ci_low"]) / (o["ci_high"] - o["ci_low"])
                     if c.get("ci_low") is not None and o.get("ci_low") is not None else None)
            lines.append(f"| {r['n']} | {c.get('cpu_seconds', float('nan')):.2f} | "
                         f"{o.get('cpu_seconds', float('nan')):.3f} | "
                         f"{'-' if ratio is None else f'{ratio:.0f}'} | {c.get('covers', '-')} | "
                         f"{o.get('covers', '-')} | {'-' if width is None else f'{width:.2f}'} | "
                         f"{c.get('status')} |")
        flat = [{"n": r["n"], "c": r["csympnet"].get("cpu_seconds"),
                 "o": r["oracle"].get("cpu_seconds")} for r in sub]
        sc, so = slope(flat, "c"), slope(flat, "o")
        lines += ["", f"log-log slope of CPU seconds against N over N >= 10^4: csympnet "
                  f"{'-' if sc is None else f'{sc:.2f}'}, oracle {'-' if so is None else f'{so:.2f}'}",
                  ""]
    return "\n".join(lines) + "\n"


def figure(rows, args, path, key="n", xlabel="samples in the record"):
    """CPU seconds of csympnet and the oracle against rows' `key`, log-log, per observation"""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5.5, 4))
    for obs, mark in zip(args.observed, ("o", "s")):
        sub = [r for r in rows if r["observed"] == obs]
        x = [r[key] for r in sub]
        ax.loglog(x, [r["csympnet"].get("cpu_seconds", np.nan) for r in sub], mark + "-",
                  label=f"csympnet fit ({obs})")
        ax.loglog(x, [r["oracle"].get("cpu_seconds", np.nan) for r in sub], mark + "--",
                  label=f"oracle ({obs})")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("CPU seconds")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--csympnet", default=os.path.join(HERE, "..", "build", "bin", "csympnet"))
    ap.add_argument("--lengths", default="1000,3162,10000,31623,100000")
    ap.add_argument("--observed", default="momenta,positions")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=1800)
    ap.add_argument("--figure", action="store_true")
    args = ap.parse_args()
    try:
        lengths = [int(x) for x in args.lengths.split(",")]
    except ValueError:
        ap.error(f"--lengths: expected comma-separated integers, got {args.lengths!r}")
    if any(n < 100 for n in lengths):
        ap.error("--lengths: each length must be at least 100 samples")
    args.observed = args.observed.split(",")
    if any(o not in ("momenta", "positions") for o in args.observed):
        ap.error(f"--observed: expected momenta and/or positions, got {args.observed}")
    if not os.path.isfile(args.csympnet):
        ap.error(f"--csympnet: no such file {args.csympnet}")
    os.makedirs(args.out, exist_ok=True)
    import scipy.optimize  # noqa: F401  (imported before any timing)
    install_stop_handlers()
    rows = []
    try:
        for obs in args.observed:
            for n in lengths:
                t, q, p, tr = record(n, args.seed, obs == "momenta")
                d = os.path.join(args.out, f"{obs}-{n}")
                os.makedirs(d, exist_ok=True)
                path = os.path.join(d, "record.csv")
                write_csv(path, t, q, p)
                c = run_csympnet(os.path.abspath(args.csympnet), path, os.path.join(d, "fit"), [],
                                 args.timeout, cpu=True)
                c0 = time.process_time()
                o = oracle(t, q, p, tr, args.seed)
                o["cpu_seconds"] = time.process_time() - c0
                for r in (c, o):
                    if r.get("ci_low") is not None and r.get("ci_high") is not None:
                        r["covers"] = bool(r["ci_low"] <= tr["gamma"] <= r["ci_high"])
                rows.append({"observed": obs, "n": n, "truth": tr,
                             "csympnet": {k: v for k, v in c.items() if k != "command"},
                             "oracle": o})
                print(f"{obs} N={n}: csympnet {c.get('cpu_seconds', float('nan')):.2f} CPU s "
                      f"({c.get('status')}), oracle {o['cpu_seconds']:.3f} CPU s", flush=True)
    except Interrupted:
        print("interrupted: writing what is done", file=sys.stderr)
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump({"config": {"lengths": lengths, "observed": args.observed, "seed": args.seed,
                              "csympnet": args.csympnet, "h": H, "noise": NOISE},
                   "rows": rows}, f, indent=1)
    with open(os.path.join(args.out, "summary.md"), "w") as f:
        f.write(summarize(rows, args))
    if args.figure and rows:
        figure(rows, args, os.path.join(args.out, "cost_scaling.png"))
    print(open(os.path.join(args.out, "summary.md")).read())


if __name__ == "__main__":
    main()
