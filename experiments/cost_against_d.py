#!/usr/bin/env python3
"""What a fit costs against the number of degrees of freedom: `csympnet fit` beside the
parametric oracle on one damped chain record of d masses, d from 1 up (docs/benchmarks.md,
"A fit's cost against d").

    /usr/bin/python3 experiments/cost_against_d.py --out DIR [--csympnet PATH]
        [--dims 1,2,4,8,10,16,20] [--samples 3200] [--observed momenta,positions] [--seed 1]
        [--fit-args "--core library"] [--figure]

The record: d unit masses in a line between two fixed walls, joined by springs of stiffness
k = 1 (d + 1 springs), each mass damped by gamma p: q'' = -k T q - gamma q' with T the
tridiagonal (2, -1) matrix. One trajectory of N samples at 12 samples a period of the fastest
mode (h = 2 pi / (12 omega_max), omega_max = 2 sin(d pi / (2 (d + 1)))), gamma = 4 / (N h) so
that every record decays by the same factor e^-2 whatever d, from q and p each drawn
0.3 N(0, 1) per mass. The exact solution (the chain's sine modes, each a damped oscillator);
Gaussian noise of 0.5% of each column's spread (q, and p = q' with momenta). Every record of
one d is drawn from the seed and d alone.

The oracle is the true form fitted by least squares (scipy.optimize.least_squares on k, gamma
and each mode's start, the exact solution in closed form), started at the truth with k and
gamma times exp(0.2 z) and the modes' starts by linear least squares at those, over growing
prefixes of the record (a frequency started off drifts a long record's phase); gamma +- 1.96
Gauss-Newton standard errors. Its cost is the Python process time of the fit; csympnet's is the
CPU seconds of the `fit` child (wait4). Both go per d, with the estimate, its interval and
whether it covers, into DIR/results.json and DIR/summary.md (and the figure DIR/cost_against_d.png
with --figure). Ctrl-C stops the child and writes what is done.
"""
import argparse
import json
import math
import os
import shlex
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from cost_scaling import figure, install_stop_handlers  # noqa: E402
from idbench.common import Interrupted  # noqa: E402
from idbench.peers.csympnet import run_csympnet  # noqa: E402

STIFFNESS = 1.0
SAMPLES_PER_FAST_PERIOD = 12
NOISE = 0.005
AMPLITUDE = 0.3
Z95 = 1.959963984540054


def modes(d):
    """The chain's mode shapes (columns, orthonormal) and T's eigenvalues."""
    j = np.arange(1, d + 1)
    shapes = math.sqrt(2.0 / (d + 1)) * np.sin(np.outer(j, j) * math.pi / (d + 1))
    return shapes, 4.0 * np.sin(j * math.pi / (2.0 * (d + 1))) ** 2


def truth_for(d, n):
    omega_max = 2.0 * math.sqrt(STIFFNESS) * math.sin(d * math.pi / (2.0 * (d + 1)))
    h = 2.0 * math.pi / (SAMPLES_PER_FAST_PERIOD * omega_max)
    return {"d": d, "n": n, "h": h, "k": STIFFNESS, "gamma": 4.0 / (n * h)}


def modal_basis(t, k, gamma, lam):
    """Per mode j, the responses to a unit start of eta_j and of eta_j': position and velocity
    (each len(t) x d), for eta'' = -k lam eta - gamma eta' (underdamped)."""
    wd = np.sqrt(np.maximum(k * lam - 0.25 * gamma * gamma, 1e-300))
    e = np.exp(-0.5 * gamma * t)[:, None]
    c, s = np.cos(np.outer(t, wd)), np.sin(np.outer(t, wd))
    # eta = e (a c + b s) with a = eta0, b = (v0 + gamma eta0 / 2) / wd
    pos_a = e * (c + 0.5 * gamma * s / wd)
    pos_v = e * s / wd
    vel_a = e * (-0.5 * gamma * (c + 0.5 * gamma * s / wd) + wd * (-s + 0.5 * gamma * c / wd))
    vel_v = e * (-0.5 * gamma * s / wd + c)
    return pos_a, pos_v, vel_a, vel_v


def solution(t, k, gamma, eta0, v0, shapes, lam):
    pa, pv, va, vv = modal_basis(t, k, gamma, lam)
    eta = pa * eta0 + pv * v0
    vel = va * eta0 + vv * v0
    return eta @ shapes.T, vel @ shapes.T


def record(d, n, seed, momenta):
    tr = truth_for(d, n)
    shapes, lam = modes(d)
    rng = np.random.default_rng([seed, d])
    q0 = AMPLITUDE * rng.standard_normal(d)
    p0 = AMPLITUDE * rng.standard_normal(d)
    t = np.arange(n) * tr["h"]
    q, p = solution(t, tr["k"], tr["gamma"], shapes.T @ q0, shapes.T @ p0, shapes, lam)
    noise = np.random.default_rng([seed, d, 2])
    qn = q + NOISE * q.std(axis=0) * noise.standard_normal(q.shape)
    pn = p + NOISE * p.std(axis=0) * noise.standard_normal(p.shape)
    return t, qn, (pn if momenta else None), tr


def write_csv(path, t, q, p):
    d = q.shape[1]
    cols = np.column_stack([t, q] + ([] if p is None else [p]))
    header = "t," + ",".join([f"q{i + 1}" for i in range(d)] +
                             ([] if p is None else [f"p{i + 1}" for i in range(d)]))
    np.savetxt(path, cols, delimiter=",", header=header, comments="", fmt="%.17g")


def oracle(t, q, p, tr, seed):
    """The true form by least squares: x = (k, gamma, eta0 (d), eta0' (d))."""
    from scipy.optimize import least_squares
    d = tr["d"]
    shapes, lam = modes(d)
    rng = np.random.default_rng([seed, d, 1])
    z = np.exp(0.2 * np.clip(rng.standard_normal(2), -2, 2))
    k0, g0 = tr["k"] * z[0], tr["gamma"] * z[1]
    sq = q.std(axis=0)
    sp = p.std(axis=0) if p is not None else None

    def residuals(x, m):
        qm, vm = solution(t[:m], x[0], x[1], x[2:2 + d], x[2 + d:], shapes, lam)
        r = [((qm - q[:m]) / sq).ravel()]
        if p is not None:
            r.append(((vm - p[:m]) / sp).ravel())
        return np.concatenate(r)

    # The modes' starts by linear least squares at the started k and gamma (the residuals are
    # linear in them), over the first stage.
    stages, m = [], max(min(len(t) // 10, 10000), 50)
    while m < len(t):
        stages.append(m)
        m *= 4
    stages.append(len(t))
    pa, pv, va, vv = modal_basis(t[:stages[0]], k0, g0, lam)
    cols = []
    for j in range(d):
        for basis_q, basis_v in ((pa, va), (pv, vv)):
            cq = np.outer(basis_q[:, j], shapes[:, j]) / sq
            c = [cq.ravel()]
            if p is not None:
                c.append((np.outer(basis_v[:, j], shapes[:, j]) / sp).ravel())
            cols.append(np.concatenate(c))
    a = np.column_stack(cols)
    y = [(q[:stages[0]] / sq).ravel()]
    if p is not None:
        y.append((p[:stages[0]] / sp).ravel())
    coef = np.linalg.lstsq(a, np.concatenate(y), rcond=None)[0]
    x = np.concatenate([[k0, g0], coef[0::2], coef[1::2]])
    lower = np.full(x.size, -np.inf)
    lower[:2] = 0.0
    fit = None
    for m in stages:
        fit = least_squares(lambda xx, m=m: residuals(xx, m), x if fit is None else fit.x,
                            method="trf", x_scale="jac", bounds=(lower, np.inf))
    r = fit.fun
    s2 = float(r @ r) / max(r.size - x.size, 1)
    cov = s2 * np.linalg.pinv(fit.jac.T @ fit.jac)
    se = math.sqrt(max(cov[1, 1], 0.0))
    g = float(fit.x[1])
    return {"gamma_hat": g, "ci_low": g - Z95 * se, "ci_high": g + Z95 * se,
            "nfev": int(fit.nfev)}


def summarize(rows, args):
    lines = ["# A fit's cost against d", "",
             f"seed {args.seed}, {args.samples} samples, csympnet `{args.csympnet}` "
             f"`{' '.join(args.fit_args)}`; CPU seconds (csympnet: wait4 of `fit`; oracle: "
             "process time of its least squares)", ""]
    for obs in args.observed:
        sub = [r for r in rows if r["observed"] == obs]
        if not sub:
            continue
        lines += [f"## {obs}", "",
                  "| d | csympnet CPU s | core | oracle CPU s | csympnet covers | oracle covers | "
                  "csympnet width / oracle's | csympnet status |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in sub:
            c, o = r["csympnet"], r["oracle"]
            width = ((c["ci_high"] - c["ci_low"]) / (o["ci_high"] - o["ci_low"])
                     if c.get("ci_low") is not None and o.get("ci_low") is not None else None)
            lines.append(f"| {r['d']} | {c.get('cpu_seconds', float('nan')):.2f} | "
                         f"{c.get('core_type', '-')} | {o.get('cpu_seconds', float('nan')):.3f} | "
                         f"{c.get('covers', '-')} | {o.get('covers', '-')} | "
                         f"{'-' if width is None else f'{width:.2f}'} | {c.get('status')} |")
        lines.append("")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--csympnet", default=os.path.join(HERE, "..", "build", "bin", "csympnet"))
    ap.add_argument("--dims", default="1,2,4,8,10,16,20")
    ap.add_argument("--samples", type=int, default=3200)
    ap.add_argument("--observed", default="momenta,positions")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--fit-args", default="", help="more options of `csympnet fit`, one string")
    ap.add_argument("--timeout", type=float, default=3600)
    ap.add_argument("--figure", action="store_true")
    args = ap.parse_args()
    try:
        dims = [int(x) for x in args.dims.split(",")]
    except ValueError:
        ap.error(f"--dims: expected comma-separated integers, got {args.dims!r}")
    if any(d < 1 or d > 200 for d in dims):
        ap.error("--dims: each d must be from 1 to 200")
    if args.samples < 100:
        ap.error("--samples: at least 100")
    args.observed = args.observed.split(",")
    if any(o not in ("momenta", "positions") for o in args.observed):
        ap.error(f"--observed: expected momenta and/or positions, got {args.observed}")
    if not os.path.isfile(args.csympnet):
        ap.error(f"--csympnet: no such file {args.csympnet}")
    try:
        args.fit_args = shlex.split(args.fit_args)
    except ValueError as e:
        ap.error(f"--fit-args: {e}")
    os.makedirs(args.out, exist_ok=True)
    import scipy.optimize  # noqa: F401  (imported before any timing)
    install_stop_handlers()
    rows = []
    try:
        for obs in args.observed:
            for d in dims:
                t, q, p, tr = record(d, args.samples, args.seed, obs == "momenta")
                sub = os.path.join(args.out, f"{obs}-d{d}")
                os.makedirs(sub, exist_ok=True)
                path = os.path.join(sub, "record.csv")
                write_csv(path, t, q, p)
                c = run_csympnet(os.path.abspath(args.csympnet), path, os.path.join(sub, "fit"),
                                 args.fit_args, args.timeout, cpu=True)
                c0 = time.process_time()
                o = oracle(t, q, p, tr, args.seed)
                o["cpu_seconds"] = time.process_time() - c0
                for r in (c, o):
                    if r.get("ci_low") is not None and r.get("ci_high") is not None:
                        r["covers"] = bool(r["ci_low"] <= tr["gamma"] <= r["ci_high"])
                rows.append({"observed": obs, "d": d, "truth": tr,
                             "csympnet": {k: v for k, v in c.items() if k != "command"},
                             "oracle": o})
                print(f"{obs} d={d}: csympnet {c.get('cpu_seconds', float('nan')):.2f} CPU s "
                      f"({c.get('status')}, {c.get('core_type')}), oracle "
                      f"{o['cpu_seconds']:.3f} CPU s", flush=True)
    except Interrupted:
        print("interrupted: writing what is done", file=sys.stderr)
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump({"config": {"dims": dims, "samples": args.samples, "observed": args.observed,
                              "seed": args.seed, "csympnet": args.csympnet,
                              "fit_args": args.fit_args, "noise": NOISE,
                              "stiffness": STIFFNESS, "amplitude": AMPLITUDE},
                   "rows": rows}, f, indent=1)
    with open(os.path.join(args.out, "summary.md"), "w") as f:
        f.write(summarize(rows, args))
    if args.figure and rows:
        figure(rows, args, os.path.join(args.out, "cost_against_d.png"), key="d",
               xlabel="degrees of freedom d")
    print(open(os.path.join(args.out, "summary.md")).read())


if __name__ == "__main__":
    main()
