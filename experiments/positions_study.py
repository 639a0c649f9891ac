#!/usr/bin/env python3
"""Coverage of `csympnet fit` on records of positions alone, beside a parametric fit.

Each case is one long free decay of a one-degree-of-freedom system, as a camera or an
encoder records it: positions only, one record, a few to fifty samples per period, noise of
a given share of the positions' spread. The systems:

    linear     q'' + gamma q' + w^2 q = 0        (a viscously damped sensor, a seismometer)
    pendulum   q'' + gamma q' + w^2 sin q = 0
    duffing    q'' + gamma q' + w^2 (q + q^3) = 0

csympnet fits the positions file (`t,q1`: the momenta are hidden states). For the linear
system a parametric fit of the true form, q = A exp(-gamma t / 2) cos(w_d t + phi) + c by
least squares (scipy), gives the reference interval (estimate ± 1.96 standard errors), the
comparison a user with a known model would make.

Usage:
    /usr/bin/python3 experiments/positions_study.py --out DIR [--cases 36] [--seed 1]
        [--jobs 2] [--csympnet build/bin/csympnet]

Writes DIR/results.json (every case, its command and outcome) and DIR/summary.md.
"""
import argparse
import concurrent.futures as cf
import datetime
import json
import math
import os
import subprocess
import sys

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SYSTEMS = ["linear", "pendulum", "duffing"]
SAMPLES_PER_PERIOD = [10, 25, 50]
SIGMAS = [0.01, 0.03]


def force(system, w):
    if system == "linear":
        return lambda q: -w * w * q
    if system == "pendulum":
        return lambda q: -w * w * np.sin(q)
    return lambda q: -w * w * (q + q ** 3)


def simulate(system, gamma, w, q0, dt, n, sub=40):
    """RK4 with `sub` substeps per sample: n + 1 samples of (q, p)."""
    f = force(system, w)
    h = dt / sub
    z = np.array([q0, 0.0])
    out = [z.copy()]
    rhs = lambda s: np.array([s[1], f(s[0]) - gamma * s[1]])
    for _ in range(n):
        for _ in range(sub):
            k1 = rhs(z)
            k2 = rhs(z + 0.5 * h * k1)
            k3 = rhs(z + 0.5 * h * k2)
            k4 = rhs(z + h * k3)
            z = z + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(z.copy())
    return np.array(out)


def plan(n, seed):
    rng = np.random.default_rng(seed)
    cases = []
    for k in range(n):
        system = SYSTEMS[k % len(SYSTEMS)]
        spp = SAMPLES_PER_PERIOD[(k // len(SYSTEMS)) % len(SAMPLES_PER_PERIOD)]
        sigma = SIGMAS[(k // (len(SYSTEMS) * len(SAMPLES_PER_PERIOD))) % len(SIGMAS)]
        w = float(np.exp(rng.uniform(np.log(0.5), np.log(8.0))))
        # the amplitude falls by a factor 5 to 50 over the record of 20 to 40 periods
        periods = float(rng.uniform(20, 40))
        fall = float(np.exp(rng.uniform(np.log(5), np.log(50))))
        gamma = 2.0 * math.log(fall) / (periods * 2 * math.pi / w)
        q0 = float(rng.uniform(0.5, 1.5)) * (1.0 if system != "duffing" else 1.2)
        cases.append({"id": f"p{k:03d}-{system}", "system": system, "samples_per_period": spp,
                      "sigma": sigma, "omega": w, "gamma": gamma, "q0": q0,
                      "periods": periods, "seed": [seed, k]})
    return cases


def parametric(t, q):
    """q = A e^{-g t/2} cos(wd t + phi) + c by least squares: (g, standard error)."""
    from scipy.optimize import least_squares
    # start: the frequency from the spectrum, the decay from the envelope's log-slope
    qc = q - q.mean()
    spec = np.abs(np.fft.rfft(qc * np.hanning(len(qc))))
    freqs = np.fft.rfftfreq(len(qc), d=float(np.median(np.diff(t))))
    wd = 2 * np.pi * freqs[1 + int(np.argmax(spec[1:]))]
    half = len(q) // 2
    a1, a2 = np.std(qc[:half]), np.std(qc[half:])
    g0 = max(2.0 * math.log(max(a1, 1e-12) / max(a2, 1e-12)) / (t[half] - t[0]), 1e-3)

    def res(x):
        a, g, w, phi, c = x
        return a * np.exp(-g * t / 2) * np.cos(w * t + phi) + c - q

    best = None
    for phi in np.linspace(0, 2 * np.pi, 8, endpoint=False):
        r = least_squares(res, [np.abs(qc).max(), g0, wd, phi, q.mean()], method="lm")
        if best is None or r.cost < best.cost:
            best = r
    jac = best.jac
    dof = max(1, len(q) - 5)
    s2 = 2 * best.cost / dof
    cov = s2 * np.linalg.pinv(jac.T @ jac)
    return float(best.x[1]), float(math.sqrt(max(cov[1, 1], 0.0)))


def run_case(case, args):
    rng = np.random.default_rng(case["seed"])
    w = case["omega"]
    dt = 2 * math.pi / w / case["samples_per_period"]
    n = int(round(case["periods"] * case["samples_per_period"]))
    z = simulate(case["system"], case["gamma"], w, case["q0"], dt, n)
    t = dt * np.arange(n + 1)
    q = z[:, 0] + case["sigma"] * np.std(z[:, 0]) * rng.standard_normal(n + 1)
    cdir = os.path.join(args.out, "cases", case["id"])
    os.makedirs(cdir, exist_ok=True)
    data = os.path.join(cdir, "positions.csv")
    with open(data, "w") as f:
        f.write("t,q1\n" + "".join(f"{a!r},{b!r}\n" for a, b in zip(t, q)))
    out = os.path.join(cdir, "fit")
    cmd = [args.csympnet, "fit", data, "--out", out, "--force", "-q", "--no-figures"]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    res = {"command": cmd, "returncode": proc.returncode}
    try:
        with open(os.path.join(out, "report.json")) as f:
            rep = json.load(f)
        res.update(verdict=rep["verdict"], gamma_hat=rep["gamma_hat"],
                   low=rep["gamma_ci_low"], high=rep["gamma_ci_high"],
                   reasons=rep["reasons"])
    except (OSError, ValueError, KeyError) as e:
        res.update(verdict="failed", reason=f"{type(e).__name__}: {e}; {proc.stderr[-300:]}")
    g = case["gamma"]
    if res.get("low") is not None:
        res["covers"] = res["low"] <= g <= res["high"]
    if res.get("gamma_hat") is not None:
        res["rel_err"] = abs(res["gamma_hat"] - g) / g
    case["csympnet"] = res
    if case["system"] == "linear":
        try:
            gp, se = parametric(t, q)
            case["parametric"] = {"gamma_hat": gp, "low": gp - 1.96 * se, "high": gp + 1.96 * se,
                                  "rel_err": abs(gp - g) / g,
                                  "covers": gp - 1.96 * se <= g <= gp + 1.96 * se}
            if res.get("low") is not None:
                case["overlap"] = res["low"] <= gp + 1.96 * se and gp - 1.96 * se <= res["high"]
                case["width_ratio"] = (res["high"] - res["low"]) / max(2 * 1.96 * se, 1e-300)
        except Exception as e:  # a failed reference is recorded, not fatal
            case["parametric"] = {"failed": f"{type(e).__name__}: {e}"}
    return case


def summarize(cases):
    lines = ["| group | n | identified | covered | median rel. error | p90 |",
             "|---|---|---|---|---|---|"]

    def row(name, cs):
        ident = [c for c in cs if c["csympnet"].get("verdict") == "identified"]
        cov = sum(1 for c in ident if c["csympnet"].get("covers"))
        errs = [c["csympnet"]["rel_err"] for c in cs if "rel_err" in c["csympnet"]]
        med = f"{np.median(errs):.2e}" if errs else "n/a"
        p90 = f"{np.percentile(errs, 90):.2e}" if errs else "n/a"
        lines.append(f"| {name} | {len(cs)} | {len(ident)} | {cov}/{len(ident)} | {med} | {p90} |")

    row("all", cases)
    for s in SYSTEMS:
        row(s, [c for c in cases if c["system"] == s])
    for spp in SAMPLES_PER_PERIOD:
        row(f"{spp} samples/period", [c for c in cases if c["samples_per_period"] == spp])
    for sg in SIGMAS:
        row(f"sigma {sg:g}", [c for c in cases if c["sigma"] == sg])
    lin = [c for c in cases if c["system"] == "linear" and "gamma_hat" in c.get("parametric", {})]
    if lin:
        lines += ["", "Linear records beside the parametric fit of the true form:", "",
                  "| n | parametric covered | parametric median rel. error | "
                  "csympnet intervals overlapping the parametric one | median width, csympnet "
                  "over parametric |", "|---|---|---|---|---|"]
        pc = sum(1 for c in lin if c["parametric"]["covers"])
        pe = np.median([c["parametric"]["rel_err"] for c in lin])
        ov = [c for c in lin if "overlap" in c]
        wr = [c["width_ratio"] for c in lin if "width_ratio" in c]
        wtext = f"{np.median(wr):.2f}" if wr else "n/a"
        lines.append(f"| {len(lin)} | {pc}/{len(lin)} | {pe:.2e} | "
                     f"{sum(1 for c in ov if c['overlap'])}/{len(ov)} | {wtext} |")
    return "\n".join(lines) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--cases", type=int, default=36)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--csympnet", default=os.path.join(REPO, "build", "bin", "csympnet"))
    args = ap.parse_args()
    if args.cases < 1 or args.jobs < 1:
        ap.error("--cases and --jobs must be >= 1")
    os.makedirs(args.out, exist_ok=True)
    cases = plan(args.cases, args.seed)
    done = []
    with cf.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        for k, c in enumerate(pool.map(lambda c: run_case(c, args), cases)):
            r = c["csympnet"]
            print(f"[{k + 1}/{len(cases)}] {c['id']} spp={c['samples_per_period']} "
                  f"sigma={c['sigma']:g}: {r.get('verdict')} {r.get('gamma_hat')} "
                  f"[{r.get('low')}, {r.get('high')}] true {c['gamma']:.4g}", flush=True)
            done.append(c)
    meta = {"command": " ".join([sys.executable] + sys.argv),
            "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
            "seed": args.seed, "cases": args.cases}
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump({"meta": meta, "cases": done}, f, indent=1)
    text = (f"# Positions-only study\n\n- command: `{meta['command']}`\n- date: {meta['date']}\n\n"
            + summarize(done))
    with open(os.path.join(args.out, "summary.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
