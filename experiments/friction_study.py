"""Dry friction and drag identified by `csympnet fit` (docs/identification.md, "Dry friction
and drag"): oscillators with viscous damping plus Coulomb friction, viscous only, or viscous
plus quadratic drag, recorded exactly (closed form between reversals for Coulomb friction,
RK4 at 400 substeps for drag), with measurement noise; each record fitted by the CLI; the
dissipation terms selected, their errors and whether their intervals cover the truth.

    python3 experiments/friction_study.py --cli build/bin/csympnet --cases 10 --out /tmp/fs

prints one line per record and a table per stratum. Records are drawn from seeds 1..cases
(numpy's default_rng(seed)), so a rerun gives the same records.
"""
import argparse
import json
import math
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from idbench.friction import coulomb_advance, drag_advance  # noqa: E402  (one definition)


def record(kind, omega, gamma, rate, starts, points, h, sigma, rng):
    rows = []
    for j, (q, v) in enumerate(starts):
        traj = []
        for k in range(points):
            traj.append((q, v))
            if kind == "drag":
                q, v = drag_advance(omega, gamma, rate, q, v, h)
            else:
                q, v = coulomb_advance(omega, gamma, rate if kind == "coulomb" else 0.0, q, v, h)
        z = np.array(traj)
        sd = z.std(axis=0)
        z = z + sigma * sd * rng.standard_normal(z.shape)
        for k in range(points):
            rows.append((j, k * h, z[k, 0], z[k, 1]))
    return rows


def draw(kind, seed):
    """A record of the stratum: omega in [1.5, 3], gamma in [0.03, 0.15], Coulomb friction a
    share of 10-90% of the dissipation over the first decay (the energy-equivalent rate
    4 mu / (pi omega A) against gamma / 2), drag c from 0.05 to 0.3, noise 0.1-1%."""
    rng = np.random.default_rng(seed)
    omega = rng.uniform(1.5, 3.0)
    gamma = rng.uniform(0.03, 0.15)
    sigma = rng.uniform(1e-3, 1e-2)
    starts = [(rng.uniform(0.8, 2.0) * rng.choice([-1, 1]), rng.uniform(-1, 1)) for _ in range(4)]
    rate = 0.0
    if kind == "coulomb":
        share = rng.uniform(0.1, 0.9)
        amp = 1.4
        # 4 mu / (pi omega A) = share / (1 - share) * gamma / 2
        rate = share / (1 - share) * 0.5 * gamma * math.pi * omega * amp / 4.0
    elif kind == "drag":
        rate = rng.uniform(0.05, 0.3)
    h = 2 * math.pi / omega / 30  # 30 samples a period
    points = int(round(40.0 / h))  # 40 s per record
    rows = record(kind, omega, gamma, rate, starts, points, h, sigma, rng)
    return dict(kind=kind, omega=omega, gamma=gamma, rate=rate, sigma=sigma, h=h), rows


def fit(cli, path, out, extra):
    subprocess.run([cli, "fit", path, "--out", out, "--force", "--quiet", "--no-figures"] + extra,
                   check=False, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(os.path.join(out, "report.json")) as f:
        return json.load(f)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cli", default="build/bin/csympnet")
    ap.add_argument("--cases", type=int, default=10)
    ap.add_argument("--out", default="/tmp/friction_study")
    ap.add_argument("--kinds", default="viscous,coulomb,drag")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    summary = {}
    for kind in args.kinds.split(","):
        stats = dict(n=0, identified=0, selected=0, wrong=0, g_err=[], r_err=[], g_cov=0, r_cov=0)
        for seed in range(1, args.cases + 1):
            truth, rows = draw(kind, seed)
            path = os.path.join(args.out, f"{kind}_{seed}.csv")
            with open(path, "w") as f:
                f.write("traj,t,q1,p1\n")
                for r in rows:
                    f.write("%d,%.17g,%.17g,%.17g\n" % r)
            rep = fit(args.cli, path, os.path.join(args.out, f"{kind}_{seed}"), [])
            terms = rep["dissipation"]["terms"]
            kinds = [t["kind"] for t in terms[1:]]
            stats["n"] += 1
            ident = rep["identified"]
            stats["identified"] += ident
            want = [] if kind == "viscous" else [kind]
            stats["selected"] += kinds == want
            stats["wrong"] += any(k != kind for k in kinds)
            g = rep["gamma_hat"]
            stats["g_err"].append(abs(g - truth["gamma"]) / truth["gamma"])
            lo, hi = rep["gamma_ci_low"], rep["gamma_ci_high"]
            stats["g_cov"] += lo is not None and lo <= truth["gamma"] <= hi
            line = (f"{kind:8s} seed {seed:3d}: gamma {truth['gamma']:.4g} -> {g:.4g}"
                    f" [{lo}, {hi}], terms {kinds}")
            if want and kinds == want:
                t = terms[1]
                stats["r_err"].append(abs(t["value"] - truth["rate"]) / truth["rate"])
                stats["r_cov"] += t["low"] is not None and t["low"] <= truth["rate"] <= t["high"]
                line += f", {kind} {truth['rate']:.4g} -> {t['value']:.4g} [{t['low']}, {t['high']}]"
            print(line, flush=True)
        summary[kind] = stats
    print()
    print("| records | n | identified | dissipation as true | a wrong term | gamma median rel. error"
          " | gamma covered | rate median rel. error | rate covered |")
    print("|---|---|---|---|---|---|---|---|---|")
    for kind, s in summary.items():
        med = lambda v: f"{np.median(v):.3g}" if v else "-"
        print(f"| {kind} | {s['n']} | {s['identified']} | {s['selected']} | {s['wrong']} | "
              f"{med(s['g_err'])} | {s['g_cov']} | {med(s['r_err'])} | "
              f"{s['r_cov'] if s['r_err'] else '-'} |")


if __name__ == "__main__":
    sys.exit(main())
