"""Tables and output files of the observed-records plan."""

import numpy as np

from .observed import LINEAR_STRATA, OBSERVED_METHODS, OBSERVED_STRATA
from .tables import fmt, write_plan_outputs


def _med(xs):
    xs = [x for x in xs if x is not None]
    return float(np.median(xs)) if xs else None


def _rows(cases, m):
    return [c["methods"][m] for c in cases
            if m in c["methods"] and c["methods"][m].get("status") != "skipped"]


def method_stats(cases, m):
    rs = _rows(cases, m)
    if not rs:
        return None
    ok = [r for r in rs if r.get("status") == "ok"]
    ci = [r for r in ok if r.get("covers") is not None]
    return {"n": len(rs), "median_rel_err": _med([r["rel_err"] for r in ok]),
            "covered": sum(1 for r in ci if r["covers"]), "with_interval": len(ci),
            "coverage": (sum(1 for r in ci if r["covers"]) / len(ci)) if ci else None,
            "not_identified": sum(1 for r in rs if r.get("status") == "not_identified"),
            "rejected": sum(1 for r in rs if r.get("status") == "rejected"),
            "failed": sum(1 for r in rs if r.get("status") == "failed"),
            "confident_wrong": sum(1 for r in rs if r.get("confident_wrong")),
            "median_width_over_oracle": _med([r.get("width_over_oracle") for r in ok]),
            "median_cpu_seconds": _med([r.get("cpu_seconds") for r in rs]),
            "median_cpu_over_oracle": _med([r.get("cpu_over_oracle") for r in rs]),
            "median_cpu_over_with_p": _med([r.get("cpu_over_with_p") for r in rs])}


def summarize_observed(cases):
    out = {}
    for st in ["all"] + [s for s in OBSERVED_STRATA if any(c["stratum"] == s for c in cases)]:
        sub = [c for c in cases if st == "all" or c["stratum"] == st]
        per = {m: method_stats(sub, m) for m in OBSERVED_METHODS}
        cs = _rows([c for c in sub if c["stratum"] in LINEAR_STRATA], "csympnet")
        lib = [r for r in cs if r.get("terms") is not None]
        per["csympnet_terms"] = {
            "linear_records": len(cs), "library_core": len(lib),
            "sin_cos_exp": sum(1 for r in lib if r.get("sin_cos_exp")),
            "neural_or_no_report": len(cs) - len(lib)}
        out[st] = per
    return out


def _cov(st):
    if st is None or st["coverage"] is None:
        return "n/a"
    return f"{st['covered']}/{st['with_interval']}"


def observed_tables(summary):
    lines = ["### per stratum and method\n",
             "| stratum | method | n | median rel. error | covered | not id. / rejected / failed | "
             "median width / oracle | median CPU s | median CPU / oracle |", "|" + "---|" * 9]
    for st, per in summary.items():
        for m in OBSERVED_METHODS:
            s = per.get(m)
            if s is None:
                continue
            lines.append(f"| {st} | {m} | {s['n']} | {fmt(s['median_rel_err'])} | {_cov(s)} | "
                         f"{s['not_identified']} / {s['rejected']} / {s['failed']} | "
                         f"{fmt(s['median_width_over_oracle'], 's')} | "
                         f"{fmt(s['median_cpu_seconds'], 's')} | "
                         f"{fmt(s['median_cpu_over_oracle'], 's')} |")
    lines += ["", "### per stratum: the goals' numbers\n",
              "| stratum | csympnet: median rel. error | coverage | width / oracle | textbook "
              "width / oracle | CPU csympnet / oracle | CPU positions only / with p | "
              "linear records with sin/cos/exp terms |",
              "|" + "---|" * 8]
    for st, per in summary.items():
        c, tb = per.get("csympnet"), per.get("textbook")
        terms = per["csympnet_terms"]
        tcell = (f"{terms['sin_cos_exp']}/{terms['library_core']} library fits"
                 + (f", {terms['neural_or_no_report']} neural or no report"
                    if terms["neural_or_no_report"] else "")) if terms["linear_records"] else "-"
        lines.append(
            f"| {st} | {fmt(c and c['median_rel_err'])} | {_cov(c)} | "
            f"{fmt(c and c['median_width_over_oracle'], 's')} | "
            f"{fmt(tb and tb['median_width_over_oracle'], 's')} | "
            f"{fmt(c and c['median_cpu_over_oracle'], 's')} | "
            f"{fmt(c and c['median_cpu_over_with_p'], 's')} | {tcell} |")
    return "\n".join(lines) + "\n"


def _cell(r):
    if r is None or r.get("status") == "skipped":
        return "-"
    if r.get("status") != "ok":
        g = r.get("gamma_hat")
        return r.get("status", "?").replace("_", " ") + ("" if g is None else f" ({g:.4g})")
    s = f"{r['gamma_hat']:.5g}"
    if r.get("ci_low") is not None:
        s += f" [{r['ci_low']:.5g}, {r['ci_high']:.5g}]"
    return s


def case_table(cases):
    lines = ["### every case\n",
             "| case | d | samples | samples/period | sigma | gamma | csympnet | oracle | textbook "
             "| log decrement | sindy | csympnet terms (core) | CPU s: csympnet, oracle, textbook |",
             "|" + "---|" * 13]
    for c in cases:
        m = c["methods"]
        cs = m.get("csympnet", {})
        terms = ", ".join(cs.get("terms") or []) or "-"
        core = cs.get("core_type") or "-"
        cpu = ", ".join("-" if m.get(k, {}).get("cpu_seconds") is None
                        else f"{m[k]['cpu_seconds']:.2f}" for k in ("csympnet", "oracle", "textbook"))
        lines.append(f"| {c['id']} | {c['d']} | {c['samples']} | "
                     f"{c['samples_per_fastest_period']:.0f} | {c['sigma']:.1e} | "
                     f"{c['gamma_true']:.5g} | {_cell(cs)} | {_cell(m.get('oracle'))} | "
                     f"{_cell(m.get('textbook'))} | {_cell(m.get('log_decrement'))} | "
                     f"{_cell(m.get('sindy'))} | {terms} ({core}) | {cpu} |")
    return "\n".join(lines) + "\n"


def write_observed_outputs(args, meta, cases, interrupted=False):
    done = [c for c in cases if "methods" in c]
    summary = summarize_observed(done)
    notes = ("Notes: one run, every method on the same record. The oracle is given the true unit "
             "scales and offsets and starts at the true potential parameters (gamma at the truth "
             "times exp(0.2 z)); on positions-only records it fits the whole record of positions. "
             "Widths over the oracle's are per case, then the median; CPU seconds: csympnet's "
             "from wait4, the Python peers' process_time (exact with --jobs 1). sindy has no "
             "interval. 'sin/cos/exp': csympnet library fits of linear records whose terms "
             "include a sin, cos or exp.")
    body = "\n".join([observed_tables(summary), case_table(done)])
    md = write_plan_outputs(args, meta, cases, "# Identification benchmark, observed records",
                            summary, notes, body, interrupted)
    return md, notes, body
