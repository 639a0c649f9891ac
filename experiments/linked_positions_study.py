#!/usr/bin/env python3
"""Positions-only linear records of 1 to 3 carts, beside the textbook fit of damped sinusoids.

Each case is one free decay of a chain of d masses between springs, one viscous rate gamma for
every mode (q'' = -K q - gamma q'), filmed as a camera films it: positions only, in pixels
(a scale and an offset per coordinate), Gaussian noise of a share of the spread, a few frames
dropped at random (irregular steps), one record.

Side by side in one run:
  csympnet   `csympnet fit` on the positions file (t,q1..qd), its gamma and interval;
  textbook   least squares of q_i(t) = c_i + sum_k exp(-gamma t/2) (a_ik cos w_k t + b_ik sin w_k t)
             over all coordinates at once (shared gamma and w_k: the true form of such a
             record, so also the oracle of a linear record), started at the true gamma and
             frequencies, each coordinate weighted by its own residual spread, by scipy;
             interval estimate +- z * standard error. Also the CPU seconds of both.

Usage:
    /usr/bin/python3 experiments/linked_positions_study.py --out DIR [--cases 12] [--seed 1]
        [--jobs 1] [--csympnet build/bin/csympnet] [--dofs 1,2,3] [--sigmas 0.002,0.01]
        [--forecast 20,10]

--forecast FIT_S,AHEAD_S makes records FIT_S + AHEAD_S seconds long, fits both methods on the
first FIT_S seconds, and scores each one's forecast of the rest (csympnet: the state fitted to
the last 50 positions with the model, then the map; textbook: its formula) by the RMSE per
coordinate in pixels, beside the noise.

Writes DIR/results.json (every case: its configuration, seed, command and outcome) and prints
the median width ratio and the coverage of each method.
"""
import argparse
import concurrent.futures as cf
import json
import math
import os
import subprocess
import sys
import time

import numpy as np
from scipy.linalg import expm
from scipy.optimize import least_squares

from idbench import linear  # the chains of the benchmark's observed plan: one definition

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def simulate(K, gamma, z0, t):
    d = K.shape[0]
    A = np.zeros((2 * d, 2 * d))
    A[:d, d:] = np.eye(d)
    A[d:, :d] = -K
    A[d:, d:] = -gamma * np.eye(d)
    return np.stack([expm(A * s) @ z0 for s in t])


def make_case(i, d, sigma, seed, fps=25.0, duration=58.0, drop=0.03):
    rng = np.random.default_rng([seed, i, d, int(sigma * 1e6)])
    K = linear.chain_stiffness(linear.draw_springs(rng, d))
    gamma = float(rng.uniform(0.06, 0.2))
    t = np.arange(0.0, duration, 1.0 / fps)
    keep = rng.uniform(size=t.size) >= drop
    keep[0] = keep[-1] = True
    t = t[keep]
    z0 = np.concatenate([rng.normal(size=d), np.zeros(d)])
    q = simulate(K, gamma, z0, t)[:, :d]
    spread = q.std(axis=0)
    q = q + sigma * spread * rng.normal(size=q.shape)
    scale = rng.uniform(50.0, 200.0, size=d)
    offset = rng.uniform(100.0, 500.0, size=d)
    px = q * scale + offset
    w = np.sqrt(np.linalg.eigvalsh(K))
    return {"t": t, "q": px, "gamma": gamma, "omegas": w, "d": d, "sigma": sigma,
            "noise_px": sigma * spread * scale}


def truncated(case, until):
    """The case's record up to time `until` (the rest kept apart, for the forecast)."""
    keep = case["t"] <= until
    out = dict(case)
    out["t"], out["q"] = case["t"][keep], case["q"][keep]
    out["t_ahead"], out["q_ahead"] = case["t"][~keep], case["q"][~keep]
    return out


def textbook(case, level):
    t, q, d = case["t"], case["q"], case["d"]
    w0 = case["omegas"] * (1.0 + 0.0)  # started at the true frequencies: the user's best case
    m = len(w0)

    def model(x, t=t):
        g = x[0]
        w = x[1:1 + m]
        rest = x[1 + m:].reshape(d, 1 + 2 * m)
        env = np.exp(-0.5 * g * t)
        out = np.empty((t.size, d))
        for i in range(d):
            s = rest[i, 0] * np.ones_like(t)
            for k in range(m):
                s += env * (rest[i, 1 + 2 * k] * np.cos(w[k] * t) + rest[i, 2 + 2 * k] * np.sin(w[k] * t))
            out[:, i] = s
        return out

    # Linear coefficients started by least squares at the true gamma and frequencies.
    g0 = case["gamma"]
    env = np.exp(-0.5 * g0 * t)
    cols = [np.ones_like(t)]
    for k in range(m):
        cols += [env * np.cos(w0[k] * t), env * np.sin(w0[k] * t)]
    X = np.stack(cols, axis=1)
    coef = np.linalg.lstsq(X, q, rcond=None)[0].T
    x0 = np.concatenate([[g0], w0, coef.ravel()])
    # Two passes: unweighted, then each coordinate weighted by its own residual spread (the
    # coordinates' noise differs in pixels; a pooled variance would misstate the error).
    res = least_squares(lambda x: (model(x) - q).ravel(), x0, method="lm", xtol=1e-14, ftol=1e-14)
    sd = (model(res.x) - q).std(axis=0)
    res = least_squares(lambda x: ((model(x) - q) / sd).ravel(), res.x, method="lm", xtol=1e-14,
                        ftol=1e-14)
    J = res.jac
    dof = max(1, res.fun.size - x0.size)
    s2 = float(res.fun @ res.fun) / dof
    cov = np.linalg.pinv(J.T @ J) * s2
    se = math.sqrt(max(cov[0, 0], 0.0))
    from scipy.stats import norm
    z = norm.ppf(0.5 + level / 2)
    out = {"gamma": float(res.x[0]), "low": float(res.x[0] - z * se), "high": float(res.x[0] + z * se)}
    if "t_ahead" in case:
        out["forecast_rmse_px"] = rmse(model(res.x, case["t_ahead"]), case["q_ahead"])
    return out


def rmse(pred, obs):
    return [float(v) for v in np.sqrt(np.mean((pred - obs) ** 2, axis=0))]


def csympnet_forecast(case, fit_dir, window=50):
    """The fitted model's forecast of the kept-apart positions: the state at the record's last
    sample fitted to its last `window` positions (Model.state_from_positions), then one map step
    per sample interval."""
    sys.path.insert(0, os.path.join(REPO, "build", "python"))
    import csympnet
    model = csympnet.load(os.path.join(fit_dir, "model.json"))
    state, _ = model.state_from_positions(case["q"][-window:], case["t"][-window:])
    hs = np.diff(np.concatenate([[case["t"][-1]], case["t_ahead"]]))
    path = model.rollout(state, hs)[1:, :case["d"]]
    return rmse(path, case["q_ahead"])


def run_csympnet(case, path, out_dir, exe, extra):
    names = ["t"] + [f"q{i + 1}" for i in range(case["d"])]
    np.savetxt(path, np.column_stack([case["t"], case["q"]]), delimiter=",", header=",".join(names),
               comments="", fmt="%.10g")
    cmd = [exe, "fit", "--data", path, "--out", out_dir, "--force", "--quiet", "--no-figures"] + extra
    t0 = time.time()
    with open(out_dir + ".stderr", "w") as err:
        child = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(child.pid, 0)  # this child's own CPU time, whatever runs beside it
        child.returncode = os.waitstatus_to_exitcode(status)
    secs = time.time() - t0
    cpu = usage.ru_utime + usage.ru_stime
    p = child
    p.stderr = open(out_dir + ".stderr").read()
    rep_path = os.path.join(out_dir, "report.json")
    if not os.path.exists(rep_path):
        return {"error": p.stderr[-500:], "command": cmd, "seconds": secs}
    with open(rep_path) as f:
        rep = json.load(f)
    return {"gamma": rep.get("gamma_hat"), "low": rep.get("gamma_ci_low"), "high": rep.get("gamma_ci_high"),
            "verdict": rep.get("verdict"), "exit": p.returncode, "seconds": secs, "cpu_seconds": cpu,
            "command": cmd,
            "linking": rep.get("choices", {}).get("positions", {}).get("linking"),
            "core": rep.get("choices", {}).get("core")}


def one(args, i, d, sigma):
    case = make_case(i, d, sigma, args.seed, **({"duration": args.duration} if args.forecast else {}))
    if args.forecast:
        until, _ = (float(v) for v in args.forecast.split(","))
        case = truncated(case, until)
    tag = f"d{d}_s{sigma:g}_{i}"
    path = os.path.join(args.out, tag + ".csv")
    c = run_csympnet(case, path, os.path.join(args.out, tag), args.csympnet, args.fit_args.split())
    if args.forecast and "error" not in c:
        c["forecast_rmse_px"] = csympnet_forecast(case, os.path.join(args.out, tag))
    c0 = time.thread_time()
    tb = textbook(case, 0.95)
    tb["cpu_seconds"] = time.thread_time() - c0
    return {"case": tag, "d": d, "sigma": sigma, "gamma_true": case["gamma"], "seed": args.seed,
            "csympnet": c, "textbook": tb, "noise_px": [float(v) for v in case["noise_px"]]}


def covers(r, g):
    return r.get("low") is not None and r["low"] <= g <= r["high"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--cases", type=int, default=4, help="cases per (d, sigma) (default 4)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--dofs", default="1,2")
    ap.add_argument("--sigmas", default="0.002,0.01")
    ap.add_argument("--csympnet", default=os.path.join(REPO, "build", "bin", "csympnet"))
    ap.add_argument("--fit-args", default="")
    ap.add_argument("--forecast", default="",
                    help="FIT_S,AHEAD_S: fit the first FIT_S seconds only and forecast the next "
                         "AHEAD_S (RMSE per coordinate in pixels, beside the noise)")
    args = ap.parse_args()
    if args.forecast:
        until, ahead = (float(v) for v in args.forecast.split(","))
        args.duration = until + ahead
    os.makedirs(args.out, exist_ok=True)
    jobs = [(i, int(d), float(s)) for d in args.dofs.split(",") for s in args.sigmas.split(",")
            for i in range(args.cases)]
    with cf.ThreadPoolExecutor(args.jobs) as ex:
        results = list(ex.map(lambda j: one(args, *j), jobs))
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump({"config": vars(args), "results": results}, f, indent=1, default=float)
    for r in results:
        c, tb, g = r["csympnet"], r["textbook"], r["gamma_true"]
        cw = (c["high"] - c["low"]) if c.get("low") is not None else float("nan")
        tw = tb["high"] - tb["low"]
        print(f"{r['case']:>16} true {g:.5f}  csympnet {c.get('gamma') or float('nan'):.5f} "
              f"w {cw:.2e} cov {int(covers(c, g))} [{c.get('verdict')}, {c.get('cpu_seconds', 0):.1f} CPU s]  "
              f"textbook {tb['gamma']:.5f} w {tw:.2e} cov {int(covers(tb, g))} [{tb['cpu_seconds']:.2f} CPU s]  "
              f"ratio {cw / tw:.2f}")
    ratios = [((r["csympnet"]["high"] - r["csympnet"]["low"]) / (r["textbook"]["high"] - r["textbook"]["low"]))
              for r in results if r["csympnet"].get("low") is not None]
    print(f"median width ratio csympnet/textbook: {np.median(ratios) if ratios else float('nan'):.2f} "
          f"over {len(ratios)} identified of {len(results)}")
    if args.forecast:
        ratios_c = [max(np.array(r["csympnet"]["forecast_rmse_px"]) / np.array(r["noise_px"]))
                    for r in results if "forecast_rmse_px" in r["csympnet"]]
        ratios_t = [max(np.array(r["textbook"]["forecast_rmse_px"]) / np.array(r["noise_px"]))
                    for r in results]
        print(f"forecast RMSE over the noise, worst coordinate, median: csympnet "
              f"{np.median(ratios_c):.2f}, textbook {np.median(ratios_t):.2f}")
    print("coverage csympnet:", sum(covers(r["csympnet"], r["gamma_true"]) for r in results), "/", len(results),
          " textbook:", sum(covers(r["textbook"], r["gamma_true"]) for r in results), "/", len(results))


if __name__ == "__main__":
    sys.exit(main())
