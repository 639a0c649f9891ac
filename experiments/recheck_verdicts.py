#!/usr/bin/python3
"""Re-applies the rules of csympnet fit's model checks to the reports an identification
benchmark run wrote, with given thresholds, and prints the false alarms (valid cases), the
detections (violation cases) and the verdicts that follow.

The checks' statistics (p-values, effects) do not depend on the thresholds, so a run made with
one set of thresholds tells what any other set would have decided, case by case. The rules
are those of src/identify/model_checks.cpp and identify_assess.cpp:

  - a check fails when it is applicable, its p-value is below alpha and its effect exceeds its
    threshold (dissipation: as the report says, unless the fit in reversed time found growth
    too: then it is a bias, not energy input);
  - linear_damping is not decided when one_rate fails too;
  - no check fails when the model explains too little of the held-out motion (held-out
    relative residual > 0.9, or squared error > 0.5 of a pure contraction's);
  - the verdict is "model rejected" when a check fails, else "identified" when no other
    reason was given, else "not identified".

    /usr/bin/python3 experiments/recheck_verdicts.py /tmp/idbench            # library defaults
    /usr/bin/python3 experiments/recheck_verdicts.py /tmp/idv --alpha 0.01   # another alpha

Needs only the Python standard library.
"""
import argparse
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from idbench.common import violation_reference  # noqa: E402  (the standard library only)

CHECKS = ["measured_momenta", "dissipation", "linear_damping", "one_rate", "residuals"]


def decide(report, a):
    """(failed check names, verdict, interval or None) under thresholds a."""
    checks = {c["name"]: c for c in report.get("checks") or []}
    q = report.get("quality", {})
    usable = (q.get("val_relative_residual", 0.0) <= 0.9 and q.get("null_ratio", 0.0) <= 0.5)
    size = {"linear_damping": a.rate_change, "one_rate": a.rate_spread,
            "residuals": a.residual_share}

    def fails(name):
        c = checks.get(name)
        if c is None or not c.get("applicable"):
            return False
        if name == "measured_momenta":  # a property of the data: its rule is in the report
            return not c.get("passed", True)
        if name == "dissipation":
            # Growth is confirmed by the fit in reversed time; a record that seems to grow in
            # both directions is a bias, not energy input (identify.cpp, confirm_growth).
            rev = (c.get("details") or {}).get("reversed_time_fit") or {}
            both = any("the motion grows" in x for x in rev.get("reasons", []))
            return not c.get("passed", True) and not both
        p, e = c.get("p_value"), c.get("effect")
        if p is None or e is None:
            return False
        alpha = a.alpha_linear_damping if name == "linear_damping" else a.alpha
        return p < alpha and abs(e) > size[name]

    # measured_momenta tests the data alone and stays decided when the model is not usable
    failed = [n for n in CHECKS if (usable or n == "measured_momenta") and fails(n)]
    if "linear_damping" in failed and "one_rate" in failed:
        failed.remove("linear_damping")
    others = [r for r in report.get("reasons", []) if not r.startswith("the model's assumption")]
    if report.get("stopped"):
        verdict = "interrupted"
    elif failed:
        verdict = "model rejected"
    elif others:
        verdict = "not identified"
    else:
        verdict = "identified"
    iv = report.get("interval") or {}
    interval = (iv.get("low"), iv.get("high")) if verdict == "identified" else None
    return failed, verdict, interval


def load(out):
    with open(os.path.join(out, "results.json")) as f:
        res = json.load(f)
    cases = res["cases"] if isinstance(res, dict) else res
    rows = []
    for c in cases:
        path = os.path.join(out, "cases", c["id"], "csympnet", "report.json")
        if not os.path.exists(path):
            continue
        with open(path) as f:
            rows.append((c, json.load(f)))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out", help="an identification benchmark's --out directory")
    ap.add_argument("--alpha", type=float, default=0.001)
    ap.add_argument("--alpha-linear-damping", type=float, default=0.01)
    ap.add_argument("--rate-change", type=float, default=0.3)
    ap.add_argument("--rate-spread", type=float, default=0.5)
    ap.add_argument("--residual-share", type=float, default=0.15)
    a = ap.parse_args()
    rows = load(a.out)
    if not rows:
        sys.exit(f"{a.out}: no case with a csympnet report")
    valid = [(c, r) for c, r in rows if "violation" not in c["strata"]]
    viol = [(c, r) for c, r in rows if "violation" in c["strata"]]
    print(f"thresholds: alpha {a.alpha:g} (linear damping {a.alpha_linear_damping:g}), "
          f"rate change {a.rate_change:g}, rate spread "
          f"{a.rate_spread:g}, residual share {a.residual_share:g}\n")
    if valid:
        n = len(valid)
        per = {k: 0 for k in CHECKS}
        anyf = 0
        verdicts = {}
        covered = with_interval = 0
        for c, r in valid:
            failed, verdict, iv = decide(r, a)
            for k in failed:
                per[k] += 1
            anyf += bool(failed)
            verdicts[verdict] = verdicts.get(verdict, 0) + 1
            if iv and iv[0] is not None:
                with_interval += 1
                covered += iv[0] <= c["gamma_true"] <= iv[1]
        print(f"valid cases: {n}")
        print("| check | false alarms | rate |\n|---|---|---|")
        for k in CHECKS:
            print(f"| {k} | {per[k]} | {per[k] / n:.3f} |")
        print(f"| any | {anyf} | {anyf / n:.3f} |\n")
        print("verdicts: " + ", ".join(f"{k} {v}" for k, v in sorted(verdicts.items())))
        if with_interval:
            print(f"coverage of the identified cases' intervals: {covered}/{with_interval} "
                  f"({covered / with_interval:.2f})\n")
    if viol:
        kinds = sorted({c["strata"]["violation"] for c, _ in viol})
        print(f"violation cases: {len(viol)}")
        print("| violation | n | " + " | ".join(CHECKS)
              + " | any | rejected | not identified | identified | confident |")
        print("|" + "---|" * (len(CHECKS) + 7))
        confident = []
        for kind in kinds:
            sub = [(c, r) for c, r in viol if c["strata"]["violation"] == kind]
            per = {k: 0 for k in CHECKS}
            anyf = 0
            verd = {"model rejected": 0, "not identified": 0, "identified": 0}
            conf = 0
            for c, r in sub:
                failed, verdict, iv = decide(r, a)
                for k in failed:
                    per[k] += 1
                anyf += bool(failed)
                verd[verdict] = verd.get(verdict, 0) + 1
                terms = (r.get("dissipation") or {}).get("terms") or []
                kinds = [t.get("kind") for t in terms if isinstance(t, dict)]
                _, (lo_ref, hi_ref) = violation_reference(c["violation"], kinds)
                if iv and iv[0] is not None and (iv[1] < lo_ref or iv[0] > hi_ref):
                    conf += 1
                    confident.append((c["id"], iv, (lo_ref, hi_ref)))
            m = len(sub)
            print(f"| {kind} | {m} | " + " | ".join(f"{per[k]}" for k in CHECKS)
                  + f" | {anyf}/{m} | {verd['model rejected']} | {verd['not identified']} | "
                  f"{verd['identified']} | {conf} |")
        print()
        for cid, iv, ref in confident:
            print(f"confident on violated data: {cid} interval [{iv[0]:.4g}, {iv[1]:.4g}], "
                  f"reference [{ref[0]:.4g}, {ref[1]:.4g}]")


if __name__ == "__main__":
    main()
