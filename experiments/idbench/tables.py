"""Statistics, tables and the output files (results.json, summary.md) of the main and
violation plans."""
import json
import math
import os

import numpy as np

from .common import (CHECK_NAMES, CORE_CHOICE_METHODS, METHODS, RATIO_STRATA, SHAPE_STRATA,
                     SIGMA_STRATA, STEPS_STRATA, UNITS_STRATA, VERDICTS, VIOLATION_STRATA)
from .peers.sindy import SG_WINDOW, STLSQ_RIDGE, STLSQ_THRESHOLD
from .systems import SYSTEM_NAMES

# ----------------------------------------------------------------------------------------------
# Statistics and tables


def fmt(x, kind="e"):
    if x is None:
        return "n/a"
    if kind == "s":
        return f"{x:.2f}" if x < 100 else f"{x:.0f}"
    return f"{x:.1e}"


def method_stats(cases, method):
    rs = [c["methods"][method] for c in cases if method in c.get("methods", {})]
    rs = [r for r in rs if r.get("status") != "skipped"]
    if not rs:
        return None
    errs = np.array([r["rel_err"] for r in rs if r.get("status") == "ok"])
    with_ci = [r for r in rs if r.get("status") == "ok" and r.get("covers") is not None]
    secs = [r["seconds"] for r in rs if "seconds" in r]
    return {
        "n": len(rs),
        "median": float(np.median(errs)) if errs.size else None,
        "p90": float(np.percentile(errs, 90)) if errs.size else None,
        "worst": float(errs.max()) if errs.size else None,
        "covered": sum(1 for r in with_ci if r["covers"]),
        "with_interval": len(with_ci),
        "coverage": (sum(1 for r in with_ci if r["covers"]) / len(with_ci)) if with_ci else None,
        "not_identified": sum(1 for r in rs if r.get("status") == "not_identified"),
        "rejected": sum(1 for r in rs if r.get("status") == "rejected"),
        "failed": sum(1 for r in rs if r.get("status") == "failed"),
        "confident_wrong": (sum(1 for r in rs if r.get("confident_wrong")) if method != "sindy"
                            else None),
        "err_gt_0.1": int((errs > 0.1).sum()),
        "median_seconds": float(np.median(secs)) if secs else None,
    }


GROUPS = [("all", lambda c: "all"), ("system", lambda c: c["system"]),
          ("gamma ratio", lambda c: c["strata"]["ratio"]),
          ("units", lambda c: c["strata"]["units"]), ("shape", lambda c: c["strata"]["shape"]),
          ("steps", lambda c: c["strata"]["steps"]),
          ("sigma", lambda c: f"{c['strata']['sigma']:g}")]


def groups_for(cases):
    """GROUPS, with the violation stratum after "all" when there are violation cases"""
    if any("violation" in c["strata"] for c in cases):
        return GROUPS[:1] + [("violation", lambda c: c["strata"].get("violation", "none"))] \
            + GROUPS[1:]
    return GROUPS


def group_values(gname, key, cases):
    values = []
    for c in cases:
        if key(c) not in values:
            values.append(key(c))
    order = {"violation": VIOLATION_STRATA, "system": SYSTEM_NAMES,
             "gamma ratio": RATIO_STRATA, "units": UNITS_STRATA,
             "shape": SHAPE_STRATA, "steps": STEPS_STRATA,
             "sigma": [f"{s:g}" for s in SIGMA_STRATA]}.get(gname)
    if order:
        values.sort(key=lambda v: order.index(v) if v in order else len(order))
    return values


def summarize(cases):
    out = {}
    for gname, key in groups_for(cases):
        out[gname] = {v: {m: method_stats([c for c in cases if key(c) == v], m) for m in METHODS}
                      for v in group_values(gname, key, cases)}
    return out


def tables(summary):
    lines = []
    head = ("| {} | method | n | median | p90 | worst | coverage | not id. | rejected | failed | "
            "conf. wrong | err>0.1 | median s |")
    for gname, groups in summary.items():
        lines.append(f"### {gname}\n")
        lines.append(head.format(gname))
        lines.append("|" + "---|" * 13)
        for v, per in groups.items():
            for m in METHODS:
                st = per.get(m)
                if st is None:
                    continue
                cov = ("n/a" if m == "sindy" else
                       "n/a" if st["coverage"] is None else
                       f"{st['coverage']:.2f} ({st['covered']}/{st['with_interval']})")
                cw = "n/a" if st["confident_wrong"] is None else str(st["confident_wrong"])
                lines.append(f"| {v} | {m} | {st['n']} | {fmt(st['median'])} | {fmt(st['p90'])} | "
                             f"{fmt(st['worst'])} | {cov} | {st['not_identified']} | "
                             f"{st['rejected']} | {st['failed']} | {cw} | {st['err_gt_0.1']} | "
                             f"{fmt(st['median_seconds'], 's')} |")
        lines.append("")
    return "\n".join(lines)


def integrator_table(cases):
    lines = ["### RK4 substep check (data generated again with half the substep)\n",
             "| system | case | omega_max * substep | max abs diff | max diff / coordinate std | "
             "max diff / state max-norm |", "|---|---|---|---|---|---|"]
    for c in cases:
        ch = c.get("integrator_check")
        if ch:
            lines.append(f"| {c['system']} | {c['id']} | {ch['substep'] * c['omega_max']:.1e} | "
                         f"{ch['max_abs_diff']:.1e} | {ch['max_diff_over_coordinate_std']:.1e} | "
                         f"{ch['max_diff_over_state_max_norm']:.1e} |")
    return "\n".join(lines) + "\n"


def case_counts(cases):
    lines = ["### cases per stratum value\n"]
    for gname, key in groups_for(cases)[1:]:
        counts = {v: sum(1 for c in cases if key(c) == v) for v in group_values(gname, key, cases)}
        lines.append(f"- {gname}: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    return "\n".join(lines) + "\n"


def csympnet_result(c):
    r = c.get("methods", {}).get("csympnet")
    return None if r is None or r.get("status") == "skipped" else r


def verdict_of(r):
    return {"ok": "identified", "not_identified": "not identified",
            "rejected": "rejected"}.get(r.get("status"), "failed")


def check_names(cases):
    names = list(CHECK_NAMES)
    for c in cases:
        for ch in csympnet_result(c).get("checks") or []:
            if ch["name"] not in names:
                names.append(ch["name"])
    return names


def check_counts(cases, names):
    """per check name: (applicable, failed) over the cases' csympnet checks, and the number of
    cases with any failed check"""
    per = {nm: [0, 0] for nm in names}
    anyf = 0
    for c in cases:
        chs = csympnet_result(c).get("checks") or []
        for ch in chs:
            if ch["applicable"] is not False:
                per[ch["name"]][0] += 1
            if ch["passed"] is False:
                per[ch["name"]][1] += 1
        anyf += any(ch["passed"] is False for ch in chs)
    return per, anyf


def false_alarm_tables(cases):
    """valid cases: per check, failed / applicable and failed / all; overall, per sigma, shape"""
    cs = [c for c in cases if "violation" not in c["strata"] and csympnet_result(c)
          and csympnet_result(c).get("checks") is not None]
    if not cs:
        return ""
    names = check_names(cs)
    lines = ["### csympnet model checks on valid data: false alarms\n",
             "Per check: failed / applicable (rate), then failed / all cases of the row. "
             "'any': cases with at least one failed check / all.\n",
             "| stratum | value | n | " + " | ".join(names) + " | any |",
             "|" + "---|" * (len(names) + 4)]
    groups = [("all", lambda c: "all"), ("sigma", lambda c: f"{c['strata']['sigma']:g}"),
              ("shape", lambda c: c["strata"]["shape"])]
    for gname, key in groups:
        for v in group_values(gname, key, cs):
            sub = [c for c in cs if key(c) == v]
            per, anyf = check_counts(sub, names)
            n = len(sub)
            cells = []
            for nm in names:
                a, f = per[nm]
                rate = f"{f / a:.2f}" if a else "n/a"
                cells.append(f"{f}/{a} ({rate}); {f / n:.2f} of all")
            lines.append(f"| {gname} | {v} | {n} | " + " | ".join(cells)
                         + f" | {anyf}/{n} ({anyf / n:.2f}) |")
    return "\n".join(lines) + "\n"


def violation_tables(cases):
    """violation cases: per kind and size, detection rate of each check and of any check,
    verdict shares, confident answers whose interval misses the true / equivalent gamma"""
    cs = [c for c in cases if "violation" in c["strata"] and csympnet_result(c)]
    if not cs:
        return ""
    names = check_names(cs)
    lines = ["### csympnet model checks on violation data: detection\n",
             "Per check: cases where it failed / cases (applicable in brackets when fewer). "
             "Verdict shares over all cases of the row. 'conf. wrong': identified with an "
             "interval outside the true gamma (coulomb, quadratic drag: the equivalent total at "
             "A0; nonuniform: outside [min, max] of the modal rates; energy gain: the negative "
             "gamma).\n",
             "| violation | n | " + " | ".join(names)
             + " | any | rejected | not identified | identified | failed | conf. wrong |",
             "|" + "---|" * (len(names) + 8)]
    wrong = []
    key = lambda c: c["strata"]["violation"]  # noqa: E731
    for v in group_values("violation", key, cs):
        sub = [c for c in cs if key(c) == v]
        n = len(sub)
        per, anyf = check_counts(sub, names)
        cells = []
        for nm in names:
            a, f = per[nm]
            cells.append(f"{f / n:.2f} ({f}/{n}" + (f", appl. {a})" if a < n else ")"))
        verd = [verdict_of(csympnet_result(c)) for c in sub]
        shares = [f"{verd.count(x) / n:.2f}" for x in ("rejected", "not identified",
                                                        "identified")]
        cw = [c for c in sub if csympnet_result(c).get("confident_wrong")]
        wrong += cw
        lines.append(f"| {v} | {n} | " + " | ".join(cells) + f" | {anyf / n:.2f} ({anyf}/{n}) | "
                     + " | ".join(shares) + f" | {verd.count('failed')} | {len(cw)} |")
    lines.append("")
    if wrong:
        lines.append("Confident answers on violated data (identified, interval misses):\n")
        for c in wrong:
            r = csympnet_result(c)
            ref = c["violation"]["gamma_reference_range"]
            ref_s = f"{ref[0]:.3e}" if ref[0] == ref[1] else f"[{ref[0]:.3e}, {ref[1]:.3e}]"
            lines.append(f"- {c['id']} ({c['strata']['shape']}, sigma {c['strata']['sigma']:g}):"
                         f" gamma_hat {r['gamma_hat']:.3e}, interval [{r['ci_low']:.3e}, "
                         f"{r['ci_high']:.3e}], true {ref_s}")
    else:
        lines.append("No confident answer on violated data.")
    return "\n".join(lines) + "\n"


def core_choice(cases):
    """per method of CORE_CHOICE_METHODS and system ("all" first): cases run, cases whose
    report.json says choices.core.type == "library", other core types (counts), no report or
    no core given"""
    out = {}
    for m in CORE_CHOICE_METHODS:
        rs = [(c, c["methods"][m]) for c in cases
              if m in c.get("methods", {}) and c["methods"][m].get("status") != "skipped"]
        if not rs:
            continue
        per = {}
        key = lambda c: c["system"]  # noqa: E731
        for v in ["all"] + group_values("system", key, [c for c, _ in rs]):
            sub = [r for c, r in rs if v == "all" or c["system"] == v]
            types = [r.get("core_type") for r in sub]
            other = {}
            for t in types:
                if t is not None and t != "library":
                    other[t] = other.get(t, 0) + 1
            per[v] = {"n": len(sub), "library": types.count("library"), "other": other,
                      "unknown": types.count(None)}
        out[m] = per
    return out


def core_choice_table(choice):
    if not choice:
        return ""
    lines = ["### core chosen (report.json choices.core.type)\n",
             "csympnet: how often its own choice was the Hamiltonian-library core; "
             "csympnet_library: the core forced with --core library (a check that it was "
             "used). 'unknown': no report.json, or no core in it.\n",
             "| system | method | n | library | rate | other cores | unknown |",
             "|" + "---|" * 7]
    for m, per in choice.items():
        for v, st in per.items():
            other = ", ".join(f"{k} {x}" for k, x in sorted(st["other"].items())) or "-"
            rate = f"{st['library'] / st['n']:.2f}" if st["n"] else "n/a"
            lines.append(f"| {v} | {m} | {st['n']} | {st['library']} | {rate} | {other} | "
                         f"{st['unknown']} |")
    return "\n".join(lines) + "\n"


def verdict_tables(cases):
    """csympnet's verdict counts per stratum value"""
    cs = [c for c in cases if csympnet_result(c)]
    if not cs:
        return ""
    lines = ["### csympnet verdicts per stratum\n",
             "| stratum | value | n | " + " | ".join(VERDICTS) + " |", "|" + "---|" * 7]
    for gname, key in groups_for(cs):
        for v in group_values(gname, key, cs):
            verd = [verdict_of(csympnet_result(c)) for c in cs if key(c) == v]
            lines.append(f"| {gname} | {v} | {len(verd)} | "
                         + " | ".join(str(verd.count(x)) for x in VERDICTS) + " |")
    return "\n".join(lines) + "\n"


def clean_json(x):
    if isinstance(x, dict):
        return {str(k): clean_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [clean_json(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(float(x)) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def write_plan_outputs(args, meta, cases, title, summary, notes, body, interrupted=False):
    """A plan's summary.md (title, command, machine, notes, tables) and results.json (meta,
    the summary and every finished or failed case) in args.out; returns the markdown."""
    done = [c for c in cases if "methods" in c]
    md = "\n".join([
        title + (" (interrupted, partial)" if interrupted else ""), "",
        f"- command: `{meta['command']}`", f"- date: {meta['date']}",
        f"- uname -a: `{meta['uname']}`", f"- csympnet --version: {meta['csympnet_version']}",
        f"- cases: {len(done)} of {len(cases)} planned, seed {args.seed}", "", notes, "", body])
    res = dict(meta, interrupted=interrupted, summary=summary,
               cases=[dict(c) for c in cases if "methods" in c or "error" in c])
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(clean_json(res), f, indent=1)
    with open(os.path.join(args.out, "summary.md"), "w") as f:
        f.write(md)
    return md


def write_outputs(args, meta, cases, interrupted=False):
    done = [c for c in cases if "methods" in c]
    summary = summarize(done)
    notes = (f"Notes: the oracle fits in natural units (it is given the true unit scales, q "
             f"offsets and time scale); sindy has no interval (coverage n/a) and no "
             f"'confident wrong'; error statistics are over the cases with a number "
             f"(not identified, rejected and failed cases are counted apart). sindy: local "
             f"cubic fit over {SG_WINDOW} samples, STLSQ threshold {STLSQ_THRESHOLD:g}, ridge "
             f"{STLSQ_RIDGE:g}. "
             f"The oracle's one-step least squares treats the noisy starting state of each step as "
             f"exact (errors in variables), so with noise it is biased and its interval can miss; "
             f"on noise-free data its residuals are integration error, not noise, so its "
             f"interval (width ~1e-9 relative) says nothing about coverage there.")
    if any("violation" in c["strata"] for c in done):
        notes += (" Violation cases: errors are relative to |gamma_reference| (the drawn gamma; "
                  "coulomb, quadratic drag: the equivalent total at A0; nonuniform: the mean "
                  "modal rate; energy gain: negative); 'confident wrong' there is any interval "
                  "outside gamma_reference_range (nonuniform: [min, max] modal rate), with no "
                  "error threshold.")
    choice = core_choice(done)
    checks = "\n".join(x for x in (false_alarm_tables(done), violation_tables(done),
                                    verdict_tables(done), core_choice_table(choice)) if x)
    body = "\n".join([case_counts(done), integrator_table(done), tables(summary)]
                     + ([checks] if checks else []))
    md = "\n".join([
        "# Identification benchmark" + (" (interrupted, partial)" if interrupted else ""), "",
        f"- command: `{meta['command']}`", f"- date: {meta['date']}",
        f"- uname -a: `{meta['uname']}`",
        f"- csympnet --version: {meta['csympnet_version']}",
        f"- cases: {len(done)} of {len(cases)} planned, seed {args.seed}", "", notes, "", body])
    res = dict(meta, interrupted=interrupted, summary=summary, core_choice=choice,
               cases=[dict(c) for c in cases if "methods" in c or "error" in c])
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(clean_json(res), f, indent=1)
    with open(os.path.join(args.out, "summary.md"), "w") as f:
        f.write(md)
    return md, notes, body
