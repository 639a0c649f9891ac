#!/usr/bin/env python3
"""How honest are the intervals on one friction-plan record? Monte Carlo over its noise.

The record of a friction-plan case (experiments/idbench/friction.py: the same truth, start
states and noise level) is drawn again N times with fresh noise; each draw is fitted by
`csympnet fit` (and, with --oracle, by the plan's oracle, the true form by least squares).
Printed per method: the estimates' bias and spread over their median standard error (1 and 1
for an interval that is right), the share of intervals that cover gamma and the friction or
drag rate, and the root-mean-square standardised error.

    /usr/bin/python3 experiments/friction_interval_mc.py --case f009-coulomb --seed 7 \
        --draws 30 --csympnet build/bin/csympnet --out /tmp/mc [--oracle]

The case id is as the plan names it (index and stratum); the seed is the plan's. Each draw's
files stay under --out (record rNN.csv, fit oNN/); results.json holds every estimate.
"""
import argparse
import json
import math
import os
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from idbench import friction as F  # noqa: E402
from idbench.peers.friction_oracle import friction_oracle  # noqa: E402


def plan_case(case_id, seed):
    index, stratum = int(case_id[1:4]), case_id.split("-", 1)[1]
    return {"index": index, "id": case_id, "stratum": stratum, "within": 0,
            "seed": [seed, 400000 + index], "strata": {"friction": stratum}}


def draw(rec0, truth, rng):
    """the case's exact trajectories with fresh noise of the case's level"""
    z = [F.simulate(truth["kind"], truth["omega"], truth["gamma"], truth["rate"], q0, v0,
                    truth["h"], truth["points"]) for q0, v0 in truth["starts"]]
    noisy = [zz + truth["sigma"] * zz.std(axis=0)[None, :] * rng.standard_normal(zz.shape)
             for zz in z]
    rec = dict(rec0)
    rec["q"] = np.concatenate([zz[:, 0] for zz in noisy])
    if rec0["p"] is not None:
        rec["p"] = np.concatenate([zz[:, 1] for zz in noisy])
    return rec


def csympnet_estimate(exe, path, out):
    subprocess.run([exe, "fit", path, "--out", out, "-q", "--no-figures", "--force"],
                   capture_output=True, check=False)
    try:
        with open(os.path.join(out, "report.json")) as f:
            r = json.load(f)
    except (OSError, ValueError):
        return None
    if r.get("gamma_ci_low") is None:
        return None
    rate = [t for t in r["dissipation"]["terms"] if t["kind"] != "viscous"]
    return {"gamma": r["gamma_hat"], "low": r["gamma_ci_low"], "high": r["gamma_ci_high"],
            "rate": rate[0]["value"] if rate else None,
            "rate_low": rate[0]["low"] if rate else None,
            "rate_high": rate[0]["high"] if rate else None}


def oracle_estimate(rec, truth, rng):
    r = friction_oracle(rec, truth, rng)
    rate = r.get("rate")
    return {"gamma": r["gamma_hat"], "low": r["ci_low"], "high": r["ci_high"],
            "rate": rate["value"] if rate else None, "rate_low": rate["low"] if rate else None,
            "rate_high": rate["high"] if rate else None}


def summary(rows, truth):
    g = np.array([x["gamma"] for x in rows])
    half = np.array([(x["high"] - x["low"]) / 2 for x in rows])
    se = half / 1.959963984540054
    true_g = truth["gamma"]
    out = {"n": len(rows),
           "gamma_bias_over_se": float((g.mean() - true_g) / np.median(se)),
           "gamma_sd_over_se": float(g.std() / np.median(se)),
           "gamma_covered": int(sum(x["low"] <= true_g <= x["high"] for x in rows))}
    rate = truth["rate_in_units"]
    with_rate = [x for x in rows if x["rate"] is not None and x["rate_low"] is not None]
    if rate and with_rate:
        out["rate_covered"] = int(sum(x["rate_low"] <= rate <= x["rate_high"] for x in with_rate))
        out["rate_n"] = len(with_rate)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", required=True, help="a friction-plan case id, e.g. f009-coulomb")
    ap.add_argument("--seed", type=int, default=1, help="the plan's seed")
    ap.add_argument("--draws", type=int, default=30)
    ap.add_argument("--csympnet", help="csympnet binary (omit to run the oracle alone)")
    ap.add_argument("--oracle", action="store_true", help="also fit the oracle")
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    if args.draws < 2:
        ap.error("--draws: expected at least 2")
    case = plan_case(args.case, args.seed)
    rec0, truth = F.generate_friction(case)
    os.makedirs(args.out, exist_ok=True)
    noise = np.random.default_rng([args.seed, 123])
    rows = {"csympnet": [], "oracle": []}
    for k in range(args.draws):
        rec = draw(rec0, truth, noise)
        if args.csympnet:
            path = os.path.join(args.out, f"r{k:02d}.csv")
            F.write_friction_csv(path, rec)
            est = csympnet_estimate(args.csympnet, path, os.path.join(args.out, f"o{k:02d}"))
            if est is not None:
                rows["csympnet"].append(est)
        if args.oracle:
            rows["oracle"].append(oracle_estimate(rec, truth, np.random.default_rng([args.seed, k])))
    result = {"case": args.case, "seed": args.seed, "draws": args.draws, "truth": truth,
              "estimates": rows,
              "summary": {m: summary(r, truth) for m, r in rows.items() if r}}
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(result, f, indent=1, default=float)
    for m, s in result["summary"].items():
        line = (f"{args.case} seed {args.seed} {m}: {s['n']} fits, gamma bias {s['gamma_bias_over_se']:+.2f} se,"
                f" sd {s['gamma_sd_over_se']:.2f} se, covered {s['gamma_covered']}/{s['n']}")
        if "rate_covered" in s:
            line += f", rate covered {s['rate_covered']}/{s['rate_n']}"
        print(line)


if __name__ == "__main__":
    main()
