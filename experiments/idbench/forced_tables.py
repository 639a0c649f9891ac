"""Tables and output files of the forced plan.

Per stratum (test record x system) and method, over the well-posed records (the ill-posed
ones, forced.py's sensitivity check, are counted and left out): n, the median free-run RMS
(per case the root mean square over the outputs of the per-output RMS, in the data's units; a
diverged or failed run counts as infinite), the medians of the per-case ratios to the
oracle's, to NARX's and to the test record's noise standard deviation, the diverged count.
Per system and method: gamma_hat's median relative error, coverage of the 95% interval,
median width / gamma, median width over the oracle's, median CPU seconds.
"""
import math

import numpy as np

from .forced import FORCED_EXTRA_SYSTEMS, FORCED_STRATA, FORCED_SYSTEMS
from .forced_plan import FORCED_METHODS
from .tables import fmt, write_plan_outputs

TESTS = {"multisine": "test-multisine", "rising": "test-rising"}


def _med(xs):
    xs = [x for x in xs if x is not None]
    return float(np.median(xs)) if xs else None


def case_rms(case, m, test):
    """the scalar RMS of method m on a test record: None if the method has no result there
    (skipped, unsupported), inf if it failed or diverged"""
    r = case["methods"].get(m)
    if r is None or r.get("status") in ("skipped", "unsupported"):
        return None
    t = (r.get("tests") or {}).get(test)
    if not t or t.get("rms") is None:
        return math.inf
    return math.sqrt(float(np.mean(np.square(t["rms"]))))


def _ratio(a, b):
    if a is None or b is None or not math.isfinite(b) or b == 0:
        return None
    return a / b


def rms_stats(cases, m, test):
    """over the well-posed records (forced.py: the sensitivity check); ill_posed counts the
    others"""
    ill = sum(1 for c in cases if (c.get("ill_posed") or {}).get(test)
              and case_rms(c, m, test) is not None)
    vals = [(c, case_rms(c, m, test)) for c in cases if not (c.get("ill_posed") or {}).get(test)]
    vals = [(c, v) for c, v in vals if v is not None]
    if not vals:
        return {"n": 0, "ill_posed": ill, "median_rms": None, "diverged": 0,
                "median_over_oracle": None, "median_over_narx": None,
                "median_over_noise": None} if ill else None
    noise = [c["sigma"] * math.sqrt(float(np.mean(np.square(c["q_rms"][test]))))
             for c, _ in vals]
    return {"n": len(vals), "ill_posed": ill, "median_rms": _med([v for _, v in vals]),
            "diverged": sum(1 for _, v in vals if not math.isfinite(v)),
            "median_over_oracle": _med([_ratio(v, case_rms(c, "oracle", test))
                                        for c, v in vals]),
            "median_over_narx": _med([_ratio(v, case_rms(c, "narx", test)) for c, v in vals]),
            "median_over_noise": _med([v / z for (_, v), z in zip(vals, noise)])}


def gamma_stats(cases, m):
    rs = [c["methods"][m] for c in cases if m in c["methods"]]
    rs = [r for r in rs if r.get("status") not in ("skipped", "unsupported")]
    if not rs:
        return None
    ok = [r for r in rs if r.get("status") == "ok" and r.get("gamma_hat") is not None]
    ci = [r for r in ok if r.get("covers") is not None]
    ow = []
    for c in cases:
        r, o = c["methods"].get(m, {}), c["methods"].get("oracle", {})
        if r.get("rel_width") is not None and o.get("rel_width"):
            ow.append(r["rel_width"] / o["rel_width"])
    return {"n": len(rs), "with_gamma": len(ok), "median_rel_err": _med([r["rel_err"] for r in ok]),
            "covered": sum(1 for r in ci if r["covers"]), "with_interval": len(ci),
            "median_rel_width": _med([r["rel_width"] for r in ci]),
            "median_width_over_oracle": _med(ow),
            "failed": sum(1 for r in rs if r.get("status") == "failed"),
            "median_cpu_seconds": _med([r.get("cpu_seconds") for r in rs])}


def summarize_forced(cases):
    systems = [s for s in FORCED_SYSTEMS + FORCED_EXTRA_SYSTEMS
               if any(c["system"] == s for c in cases)]
    out = {"rms": {}, "gamma": {}, "status": {}}
    for st in FORCED_STRATA:
        for sy in systems:
            sub = [c for c in cases if c["system"] == sy]
            out["rms"][f"{st}/{sy}"] = {m: rms_stats(sub, m, TESTS[st]) for m in FORCED_METHODS}
    for sy in systems:
        sub = [c for c in cases if c["system"] == sy]
        out["gamma"][sy] = {m: gamma_stats(sub, m) for m in FORCED_METHODS}
    for m in FORCED_METHODS:
        cnt = {}
        for c in cases:
            k = c["methods"].get(m, {}).get("status", "absent")
            cnt[k] = cnt.get(k, 0) + 1
        out["status"][m] = cnt
    return out


def forced_tables(summary):
    lines = ["### Free-run simulation RMS on the test records (after a 100-sample warm-up)\n",
             "| stratum | method | n | ill-posed, left out | median RMS | median RMS / oracle's | "
             "median RMS / NARX's | median RMS / noise | diverged |", "|" + "---|" * 9]
    for st, per in summary["rms"].items():
        for m in FORCED_METHODS:
            s = per.get(m)
            if s is None:
                continue
            lines.append(f"| {st} | {m} | {s['n']} | {s['ill_posed']} | {fmt(s['median_rms'])} | "
                         f"{fmt(s['median_over_oracle'], 's')} | "
                         f"{fmt(s['median_over_narx'], 's')} | "
                         f"{fmt(s['median_over_noise'], 's')} | {s['diverged']} |")
    lines += ["", "### gamma from the training record, and CPU seconds (fit and tests)\n",
              "| system | method | n | with gamma | median rel. error | covered | median width / "
              "gamma | median width / oracle's | failed | median CPU s |", "|" + "---|" * 10]
    for sy, per in summary["gamma"].items():
        for m in FORCED_METHODS:
            s = per.get(m)
            if s is None:
                continue
            cov = f"{s['covered']}/{s['with_interval']}" if s["with_interval"] else "n/a"
            lines.append(f"| {sy} | {m} | {s['n']} | {s['with_gamma']} | "
                         f"{fmt(s['median_rel_err'])} | {cov} | {fmt(s['median_rel_width'])} | "
                         f"{fmt(s['median_width_over_oracle'], 's')} | {s['failed']} | "
                         f"{fmt(s['median_cpu_seconds'], 's')} |")
    lines += ["", "status counts per method: " + "; ".join(
        f"{m}: " + ", ".join(f"{k} {v}" for k, v in sorted(c.items()))
        for m, c in summary["status"].items())]
    return "\n".join(lines) + "\n"


def case_table(cases):
    lines = ["### every case\n",
             "| case | d | sigma | gamma | oracle gamma [95%] | RMS multisine: oracle, NARX, ARX, "
             "csympnet | RMS rising: oracle, NARX, ARX, csympnet | sensitivity: multisine, "
             "rising | rising beyond train | NARX terms/output, degree | csympnet status |",
             "|" + "---|" * 11]
    for c in cases:
        o = c["methods"].get("oracle", {})
        og = (f"{o['gamma_hat']:.5g} [{o['ci_low']:.5g}, {o['ci_high']:.5g}]"
              if o.get("status") == "ok" else o.get("status", "-"))

        def cells(test):
            out = []
            for m in ("oracle", "narx", "arx", "csympnet"):
                v = case_rms(c, m, test)
                out.append("-" if v is None else ("inf" if not math.isfinite(v) else f"{v:.2e}"))
            return ", ".join(out)
        nx = c["methods"].get("narx", {}).get("extra") or {}
        cs = c["methods"].get("csympnet", {})
        sens = ", ".join(f"{(c.get('sensitivity') or {}).get(k, math.nan):.2g}"
                         for k in ("test-multisine", "test-rising"))
        lines.append(f"| {c['id']} | {c['d']} | {c['sigma']:.1e} | {c['gamma_true']:.4g} | {og} | "
                     f"{cells('test-multisine')} | {cells('test-rising')} | {sens} | "
                     f"{c['rising_share_beyond_train']:.3f} | "
                     f"{nx.get('terms_per_output', '-')}, {nx.get('degree', '-')} | "
                     f"{cs.get('status', '-')} |")
    return "\n".join(lines) + "\n"


def write_forced_outputs(args, meta, cases, interrupted=False):
    done = [c for c in cases if "methods" in c]
    summary = summarize_forced(done)
    notes = ("Notes: one run, every method on the same records. RMS in the data's units (rad for "
             "the pendulum), against the noisy test positions; 'noise' is the test record's noise "
             "standard deviation (RMS over outputs). Ratios are per case, then the median, over "
             "the well-posed records: 'sensitivity' is the change of the free run when gamma "
             "changes by 1e-4 of itself, over the noise; above 1 the record is ill-posed. The "
             "oracle is started at the true potential parameters and B, gamma at the truth times "
             "exp(0.2 z). ARX and NARX have no gamma. CPU seconds: process_time of the Python "
             "peers (exact with --jobs 1), wait4 of csympnet's fit and evaluations.")
    body = "\n".join([forced_tables(summary), case_table(done)])
    md = write_plan_outputs(args, meta, cases, "# Identification benchmark, forced records",
                            summary, notes, body, interrupted)
    return md, notes, body
