"""Tables and output files of the friction plan.

Per stratum and method: n; with gamma (a number; for csympnet identified); for csympnet the
records whose selected dissipation is the true one (no friction or drag on a viscous record)
and those with a wrong term; gamma's median relative error, coverage of its 95% interval, median
width over gamma and over the oracle's; the rate's (mu or c) median relative error and coverage;
the median CPU seconds; then every case.
"""
import math

import numpy as np

from .friction import FRICTION_STRATA
from .friction_plan import FRICTION_METHODS
from .tables import fmt, write_plan_outputs


def _med(xs):
    xs = [x for x in xs if x is not None and math.isfinite(x)]
    return float(np.median(xs)) if xs else None


def method_stats(cases, m):
    rs = [(c, c["methods"][m]) for c in cases if m in c["methods"]]
    rs = [(c, r) for c, r in rs if r.get("status") != "skipped"]
    if not rs:
        return None
    ok = [(c, r) for c, r in rs if r.get("status") == "ok"]
    ci = [r for _, r in ok if r.get("covers") is not None]
    over = []
    for c, r in ok:
        o = c["methods"].get("oracle", {})
        if r.get("rel_width") is not None and o.get("rel_width"):
            over.append(r["rel_width"] / o["rel_width"])
    rated = [r for _, r in ok if r.get("rate_rel_err") is not None]
    rate_ci = [r for r in rated if r.get("rate_covers") is not None]
    verdicts = {}
    for _, r in rs:
        verdicts[r.get("status", "absent")] = verdicts.get(r.get("status", "absent"), 0) + 1
    return {"n": len(rs), "with_gamma": len(ok),
            "as_true": (sum(1 for _, r in rs if r.get("kinds_as_true")) if m == "csympnet"
                        else None),
            "wrong_kind": (sum(1 for _, r in rs if r.get("wrong_kind")) if m == "csympnet"
                           else None),
            "gamma_median_rel_err": _med([r["rel_err"] for _, r in ok]),
            "gamma_covered": sum(1 for r in ci if r["covers"]), "gamma_with_interval": len(ci),
            "gamma_median_rel_width": _med([r["rel_width"] for r in ci]),
            "gamma_width_over_oracle": _med(over),
            "rate_n": len(rated), "rate_median_rel_err": _med([r["rate_rel_err"] for r in rated]),
            "rate_covered": sum(1 for r in rate_ci if r["rate_covers"]),
            "rate_with_interval": len(rate_ci),
            "median_cpu_seconds": _med([r.get("cpu_seconds") for _, r in rs]),
            "statuses": verdicts}


def summarize_friction(cases):
    out = {}
    for st in FRICTION_STRATA:
        sub = [c for c in cases if c["stratum"] == st]
        if sub:
            out[st] = {m: method_stats(sub, m) for m in FRICTION_METHODS}
    return out


def friction_tables(summary):
    lines = ["### gamma and the friction or drag rate, per stratum\n",
             "| stratum | method | n | with gamma | dissipation as true | a wrong term | gamma "
             "median rel. error | gamma covered | gamma median width / gamma | width / oracle's "
             "| rate median rel. error | rate covered | median CPU s | statuses |",
             "|" + "---|" * 14]
    for st, per in summary.items():
        for m in FRICTION_METHODS:
            s = per.get(m)
            if s is None:
                continue
            cov = (f"{s['gamma_covered']}/{s['gamma_with_interval']}"
                   if s["gamma_with_interval"] else "n/a")
            rcov = (f"{s['rate_covered']}/{s['rate_with_interval']}"
                    if s["rate_with_interval"] else "n/a")
            lines.append(
                f"| {st} | {m} | {s['n']} | {s['with_gamma']} | "
                f"{'-' if s['as_true'] is None else s['as_true']} | "
                f"{'-' if s['wrong_kind'] is None else s['wrong_kind']} | "
                f"{fmt(s['gamma_median_rel_err'])} | {cov} | {fmt(s['gamma_median_rel_width'])} | "
                f"{fmt(s['gamma_width_over_oracle'], 's')} | {fmt(s['rate_median_rel_err'])} | "
                f"{rcov} | {fmt(s['median_cpu_seconds'], 's')} | "
                + ", ".join(f"{k} {v}" for k, v in sorted(s["statuses"].items())) + " |")
    return "\n".join(lines) + "\n"


def _cell(r):
    if r is None or r.get("status") == "skipped":
        return "-"
    if r.get("status") != "ok":
        return r.get("status", "-")
    g = f"{r['gamma_hat']:.4g}"
    if r.get("ci_low") is not None:
        g += f" [{r['ci_low']:.4g}, {r['ci_high']:.4g}]"
    for rate in r.get("rates") or ([r["rate"]] if r.get("rate") else []):
        if rate.get("value") is None:
            continue
        g += f"; {rate['kind']}" + (f" {rate['dof']}" if rate.get("dof") else "")
        g += f" {rate['value']:.4g}"
        if rate.get("low") is not None:
            g += f" [{rate['low']:.4g}, {rate['high']:.4g}]"
    return g


def _rates(x):
    return "; ".join(f"{v:.4g}" for v in x) if isinstance(x, list) else f"{x:.4g}"


def case_table(cases):
    lines = ["### every case\n",
             "| case | kind | gamma | rate (record units) | csympnet | kinds | oracle | envelope |",
             "|" + "---|" * 8]
    for c in cases:
        t = c["truth"]
        cs = c["methods"].get("csympnet", {})
        lines.append(f"| {c['id']} | {t['kind']} | {t['gamma']:.4g} | "
                     f"{_rates(t['rate_in_units'])} | {_cell(cs)} | "
                     f"{','.join(cs.get('kinds', [])) or '-'} | "
                     f"{_cell(c['methods'].get('oracle'))} | "
                     f"{_cell(c['methods'].get('envelope'))} |")
    return "\n".join(lines) + "\n"


def write_friction_outputs(args, meta, cases, interrupted=False):
    done = [c for c in cases if "methods" in c]
    summary = summarize_friction(done)
    notes = ("Notes: one run, every method on the same records. Rates in the record's units: "
             "mu in q units per s^2 (counts for the encoder), c per q unit. The oracle is the "
             "true form with its kind known, given the true units and started near the truth "
             "(on two masses: the true form given to csympnet fit, peers/chain_oracle.py); "
             "the envelope is the user's regression of consecutive extremes on the true kind's "
             "form; csympnet runs with its defaults and chooses the dissipation itself. CPU "
             "seconds: process_time of the Python peers (exact with --jobs 1), wait4 of "
             "csympnet's fit.")
    body = "\n".join([friction_tables(summary), case_table(done)])
    md = write_plan_outputs(args, meta, cases, "# Identification benchmark, friction records",
                            summary, notes, body, interrupted)
    return md, notes, body
