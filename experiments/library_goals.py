#!/usr/bin/python3
"""The Hamiltonian-library core's goals, read from an identification benchmark's results.

    /usr/bin/python3 experiments/identification_benchmark.py --out D --library --jobs 2
    /usr/bin/python3 experiments/library_goals.py D/results.json

Prints, per method (csympnet, csympnet_library, sindy, oracle) and stratum:

    clean, inside      sigma = 0, systems whose potential the library's families hold, d <= 4
    clean, all         sigma = 0, every system
    sigma 1e-2, all    sigma = 1e-2, every system
    sigma 1e-2, inside sigma = 1e-2, systems inside the library, d <= 4

the number of cases, the median and 90th percentile of the relative error of gamma_hat (over
cases with a number), the coverage of the 95% intervals (covering / with an interval), "not
identified" and "confident wrong" counts, and the median wall seconds; then, for the
csympnet_library column on clean natural-unit cases inside the library, whether the true
terms were selected with no spurious term whose interval excludes 0 (the polynomial
reported about the data's own zero, so odd terms of a symmetric potential must contain 0),
and how often the true coefficients lie in their intervals.

Systems inside the library (its families: powers of coordinates and differences, sin/cos,
exp with learned wavenumbers): pendulum, duffing, linear, morse, toda, fpu-alpha, fpu-beta,
coupled-pendulums. Outside: henon-heiles (a q1^2 q2 term), softened-central
(1/sqrt(|q|^2 + eps^2)), double-pendulum (non-separable).
"""
import json
import sys

import numpy as np

INSIDE = {"pendulum", "duffing", "linear", "morse", "toda", "fpu-alpha", "fpu-beta",
          "coupled-pendulums"}
METHODS = ["csympnet", "csympnet_library", "sindy", "oracle"]

# The true potential's reported terms in natural units (d = 1 systems): name -> coefficient.
TRUE_TERMS = {
    "duffing": lambda th: {"q1^2": -th["a"] / 2, "q1^4": th["b"] / 4},
    "linear": lambda th: {"q1^2": th["k"] / 2},
}


def stats(cases, method):
    rows = [c["methods"].get(method, {}) for c in cases]
    rows = [r for r in rows if r.get("status") not in (None, "skipped")]
    errs = [r["rel_err"] for r in rows if r.get("status") == "ok" and "rel_err" in r]
    cov = [r["covers"] for r in rows if r.get("covers") is not None]
    secs = [r["seconds"] for r in rows if "seconds" in r]
    return {
        "n": len(rows),
        "median": float(np.median(errs)) if errs else None,
        "p90": float(np.percentile(errs, 90)) if errs else None,
        "coverage": (sum(cov), len(cov)),
        "not_identified": sum(r.get("status") == "not_identified" for r in rows),
        "rejected": sum(r.get("status") == "rejected" for r in rows),
        "failed": sum(r.get("status") == "failed" for r in rows),
        "confident_wrong": sum(bool(r.get("confident_wrong")) for r in rows),
        "seconds": float(np.median(secs)) if secs else None,
    }


def fmt(x):
    return "-" if x is None else f"{x:.2g}"


def terms_selected(case):
    """(selected, spurious, covered, n_true) for the library column on a d = 1 case with a
    polynomial truth, or None."""
    make = TRUE_TERMS.get(case["system"])
    res = case["methods"].get("csympnet_library", {})
    h = res.get("hamiltonian")
    if make is None or h is None:
        return None
    truth = make(case["theta"])
    got = {t["term"]: t for t in h["terms"]}
    selected = all(name in got for name in truth)
    spurious = 0
    covered = 0
    for name, t in got.items():
        iv = t.get("interval")
        if name in truth:
            covered += int(iv is not None and iv[0] <= truth[name] <= iv[1])
        elif iv is not None and not (iv[0] <= 0.0 <= iv[1]):
            spurious += 1
    return selected, spurious, covered, len(truth)


def main(path):
    with open(path) as f:
        cases = [c for c in json.load(f)["cases"] if "methods" in c]
    strata = {
        "clean, inside (d <= 4)": [c for c in cases if c["strata"]["sigma"] == 0 and c["system"] in INSIDE
                                   and c["d"] <= 4],
        "clean, all": [c for c in cases if c["strata"]["sigma"] == 0],
        "sigma 1e-2, all": [c for c in cases if c["strata"]["sigma"] == 1e-2],
        "sigma 1e-2, inside (d <= 4)": [c for c in cases if c["strata"]["sigma"] == 1e-2
                                        and c["system"] in INSIDE and c["d"] <= 4],
        "all": cases,
    }
    print("| stratum | method | n | median | p90 | coverage | not identified | rejected | "
          "failed | confident wrong | median s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, sub in strata.items():
        for m in METHODS:
            s = stats(sub, m)
            if s["n"] == 0:
                continue
            cov = f"{s['coverage'][0]}/{s['coverage'][1]}" if s["coverage"][1] else "-"
            print(f"| {name} | {m} | {s['n']} | {fmt(s['median'])} | {fmt(s['p90'])} | {cov} | "
                  f"{s['not_identified']} | {s['rejected']} | {s['failed']} | "
                  f"{s['confident_wrong']} | {fmt(s['seconds'])} |")
    # Ratio to the oracle at sigma 1e-2 inside, case by case.
    ratios = []
    for c in strata["sigma 1e-2, inside (d <= 4)"]:
        a, o = c["methods"].get("csympnet", {}), c["methods"].get("oracle", {})
        if a.get("status") == "ok" and o.get("status") == "ok" and o.get("rel_err", 0) > 0:
            ratios.append(a["rel_err"] / o["rel_err"])
    if ratios:
        print(f"\nsigma 1e-2 inside, csympnet / oracle relative error, case by case: median "
              f"{np.median(ratios):.2f} over {len(ratios)} cases")
    sel = [terms_selected(c) for c in cases
           if c["strata"]["sigma"] == 0 and c["strata"]["units"] == "natural" and c["system"] in TRUE_TERMS]
    sel = [s for s in sel if s is not None]
    if sel:
        ok = sum(s[0] and s[1] == 0 for s in sel)
        cov = sum(s[2] for s in sel)
        n_true = sum(s[3] for s in sel)
        print(f"terms (clean, natural units, polynomial truths, csympnet_library): true terms "
              f"selected with no spurious term outside its interval in {ok} of {len(sel)}; "
              f"true coefficients inside their intervals {cov} of {n_true}")
    # Time of clean fits the library core won, d <= 3.
    won = [c["methods"]["csympnet"]["seconds"] for c in cases
           if c["strata"]["sigma"] == 0 and c["d"] <= 3
           and c["methods"].get("csympnet", {}).get("core_type") == "library"
           and "seconds" in c["methods"]["csympnet"]]
    if won:
        print(f"clean d <= 3 cases the library core won: {len(won)}, wall seconds median "
              f"{np.median(won):.1f}, max {max(won):.1f}, <= 5 s in "
              f"{sum(w <= 5 for w in won)}")


if __name__ == "__main__":
    main(sys.argv[1])
