"""One case of the friction plan (--friction-plan): the record (idbench.friction), its CSV
file, and every method on it in one run, with each method's CPU seconds:

    csympnet   `csympnet fit FILE --out DIR -q --no-figures` (defaults: --dissipation auto);
               gamma_hat and its interval, and the report's "dissipation" terms beyond the
               viscous one: which kinds were selected, and the true kind's value and interval
    oracle     peers/friction_oracle.py: the true form, its kind given, by least squares on
               the whole record; on two masses (friction_chain.py) peers/chain_oracle.py,
               the true form given to `csympnet fit`
    envelope   peers/friction_textbook.py: the extremes' envelope regressed on the true kind's
               form ("viscous plus a constant loss" for dry friction)

Scores, against the truth in the record's units: gamma's relative error, whether its 95%
interval covers, its width over gamma; the rate's (mu or c) relative error and whether its
interval covers; for csympnet whether the kinds it selected are the true ones (none for a
viscous record) and whether it selected a wrong one. CPU seconds: process_time for the Python
peers (exact with --jobs 1), wait4 of the child for csympnet.
"""
import json
import math
import os
import shutil
import time

import numpy as np

from .common import Interrupted, check_stop
from .friction import generate_friction, write_friction_csv
from .peers.csympnet import run_csympnet
from .peers.chain_oracle import chain_oracle_arguments
from .peers.friction_oracle import friction_oracle
from .peers.friction_textbook import envelope_fit
from .runner import score

FRICTION_METHODS = ["csympnet", "oracle", "envelope"]


def _timed(fn):
    t0, c0 = time.monotonic(), time.process_time()
    try:
        r = fn()
        res = {"status": r.pop("status", "ok"), **r}
        if res["status"] == "ok" and not math.isfinite(res.get("gamma_hat", math.nan)):
            res["status"] = "failed"
    except Interrupted:
        raise
    except Exception as e:  # a peer that breaks on a case is a failure of that peer
        res = {"status": "failed", "reason": f"{type(e).__name__}: {e}"}
    res["seconds"] = time.monotonic() - t0
    res["cpu_seconds"] = time.process_time() - c0
    return res


def true_kinds(truth):
    return [] if truth["kind"] == "viscous" else ["drag" if truth["kind"] == "drag"
                                                  else "coulomb"]


def csympnet_dissipation(outdir):
    """the report's dissipation terms beyond the viscous one: [{kind, value, low, high}]"""
    try:
        with open(os.path.join(outdir, "report.json")) as f:
            rep = json.load(f)
    except (OSError, ValueError):
        return None
    terms = ((rep.get("dissipation") or {}).get("terms")) or []
    return [{k: t.get(k) for k in ("kind", "dof", "value", "low", "high")} for t in terms
            if isinstance(t, dict) and t.get("kind") != "viscous"]


def score_rate(res, truth):
    """the true kind's rate: relative error, and coverage when an interval is given"""
    want = true_kinds(truth)
    if res.get("status") != "ok" or not want:
        return res
    rate = res.get("rate")
    if rate is None or rate.get("kind") != want[0] or rate.get("value") is None:
        return res
    true = truth["rate_in_units"]
    if isinstance(true, list):  # one rate a degree of freedom: the worst of them is scored
        return _score_rates(res, true)
    res["rate_rel_err"] = abs(rate["value"] - true) / true
    if rate.get("low") is not None and rate.get("high") is not None:
        res["rate_covers"] = bool(rate["low"] <= true <= rate["high"])
    return res


def _score_rates(res, true):
    """the rates of several degrees of freedom: the largest relative error, and whether every
    interval covers (each dof's own in "rates")"""
    by_dof = {t.get("dof"): t for t in res.get("rates", [])}
    errs, covers = [], []
    for i, want in enumerate(true):
        t = by_dof.get(i + 1)
        if t is None or t.get("value") is None:
            return res
        errs.append(abs(t["value"] - want) / want)
        if t.get("low") is not None and t.get("high") is not None:
            covers.append(bool(t["low"] <= want <= t["high"]))
    res["rate_rel_err"] = max(errs)
    if len(covers) == len(true):
        res["rate_covers"] = all(covers)
        res["rate_dofs_covered"] = sum(covers)
    return res


def _csympnet_on(exe, path, outdir, extra, timeout, truth):
    """`csympnet fit` on the record with these options: its result, the kinds of dissipation
    it selected and the true kind's terms"""
    if os.path.isdir(outdir):
        shutil.rmtree(outdir)
    r = run_csympnet(exe, path, outdir, extra, timeout, cpu=True)
    terms = csympnet_dissipation(outdir) if r.get("status") in ("ok", "rejected",
                                                                  "not_identified") else None
    if terms is not None:
        kinds = sorted({t["kind"] for t in terms})
        r["kinds"] = kinds
        r["kinds_as_true"] = kinds == true_kinds(truth)
        r["wrong_kind"] = any(k not in true_kinds(truth) for k in kinds)
        mine = [t for t in terms if t["kind"] in true_kinds(truth)]
        if mine:
            r["rate"] = mine[0]
            r["rates"] = mine
    return r


def run_friction_case(case, args, exe, extra):
    check_stop()
    cdir = os.path.join(args.out, "cases", case["id"])
    os.makedirs(cdir, exist_ok=True)
    t0 = time.monotonic()
    rec, truth = generate_friction(case, args.quick)
    case["generate_seconds"] = time.monotonic() - t0
    case["truth"] = {k: v for k, v in truth.items() if k != "starts"}
    path = os.path.join(cdir, "record.csv")
    write_friction_csv(path, rec)
    case["paths"] = {"record": os.path.relpath(path, args.out)}
    rng = np.random.default_rng(case["seed"] + [1])
    if truth.get("d", 1) == 1:
        methods = {"oracle": _timed(lambda: friction_oracle(rec, truth, rng)),
                   "envelope": _timed(lambda: envelope_fit(rec, truth["kind"]))}
    else:  # idbench/friction_chain.py: the true form given to csympnet; no envelope fit
        methods = {"envelope": {"status": "skipped"}}
        if args.only_peers:
            methods["oracle"] = {"status": "skipped"}
        else:
            methods["oracle"] = _csympnet_on(exe, path, os.path.join(cdir, "oracle"),
                                             chain_oracle_arguments(extra), args.timeout, truth)
    if args.only_peers:
        methods["csympnet"] = {"status": "skipped"}
    else:
        methods["csympnet"] = _csympnet_on(exe, path, os.path.join(cdir, "csympnet"), extra,
                                           args.timeout, truth)
    for r in methods.values():
        if r.get("gamma_hat") is not None and r.get("status") == "ok":
            score(r, truth["gamma"])
            score_rate(r, truth)
    case["methods"] = {m: methods[m] for m in FRICTION_METHODS if m in methods}
    return case
