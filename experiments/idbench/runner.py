"""One case of the main and violation plans: generate, run every method, score."""
import math
import os
import shutil
import time

import numpy as np

from .common import LIBRARY_MAX_D, Interrupted, check_stop, violation_reference
from .generate import computed_momenta, generate, write_csv
from .peers.csympnet import run_csympnet
from .peers.oracle import oracle
from .peers.sindy import sindy

# ----------------------------------------------------------------------------------------------
# One case


def score(res, gamma):
    if res.get("status") != "ok":
        return res
    g = res.get("gamma_hat")
    res["rel_err"] = abs(g - gamma) / gamma
    lo, hi = res.get("ci_low"), res.get("ci_high")
    if lo is not None and hi is not None:
        res["covers"] = bool(lo <= gamma <= hi)
        res["rel_width"] = (hi - lo) / gamma
        res["confident_wrong"] = (not res["covers"]) and res["rel_err"] > 0.1
    else:
        res["covers"] = None
        res["rel_width"] = None
        res["confident_wrong"] = None
    return res


def score_violation(res, v):
    """Violation cases: the relative error against gamma_reference; an interval that lies
    outside gamma_reference_range is a confident answer on violated data (confident_wrong).
    An answer that names the family's dissipation term (violation_reference) is judged on the
    viscous part (`judged_on_viscous`)."""
    if res.get("status") != "ok":
        return res
    gamma, (ref_lo, ref_hi) = violation_reference(v, res.get("dissipation_kinds"))
    res["judged_on_viscous"] = gamma != v["gamma_reference"]
    g = res.get("gamma_hat")
    res["rel_err"] = abs(g - gamma) / abs(gamma)
    lo, hi = res.get("ci_low"), res.get("ci_high")
    if lo is not None and hi is not None:
        res["covers"] = bool(lo <= gamma <= hi)
        res["rel_width"] = (hi - lo) / abs(gamma)
        res["confident_wrong"] = bool(hi < ref_lo or lo > ref_hi)
    else:
        res["covers"] = None
        res["rel_width"] = None
        res["confident_wrong"] = None
    return res


def run_case(case, args, check_integrator, exe, extra):
    check_stop()
    cdir = os.path.join(args.out, "cases", case["id"])
    os.makedirs(cdir, exist_ok=True)
    t0 = time.monotonic()
    files, info, s = generate(case, args.quick, check_integrator)
    if args.momenta != "given":
        files = computed_momenta(files, info["d"], args.momenta)
    info["momenta"] = args.momenta
    case.update(info)
    case["generate_seconds"] = time.monotonic() - t0
    data = os.path.join(cdir, "data.csv")
    write_csv(data, files, info["d"])
    case["paths"] = {"data": os.path.relpath(data, args.out)}
    gamma = info["gamma_true"]
    scorer = score
    if "violation" in info:
        def scorer(res, gamma, v=info["violation"]):
            return score_violation(res, v)
    methods = {}
    if args.observed:
        # The same record as a user with a position sensor alone has it, and as one who
        # differences it (centred differences, numpy.gradient).
        variants = {"positions": (files, True),
                    "differenced": (computed_momenta(files, info["d"], "gradient"), False)}
        for name, (vfiles, positions_only) in variants.items():
            path = os.path.join(cdir, f"data_{name}.csv")
            write_csv(path, vfiles, info["d"], positions_only)
            case["paths"][f"data_{name}"] = os.path.relpath(path, args.out)
            if args.only_peers:
                continue
            outdir = os.path.join(cdir, f"csympnet_{name}")
            if os.path.isdir(outdir):
                shutil.rmtree(outdir)
            # The differenced momenta as a user would use them: kept (the default sets them
            # aside and gives csympnet_positions' answer).
            more = extra + (["--derived-momenta", "use"] if name == "differenced" else [])
            methods[f"csympnet_{name}"] = scorer(
                run_csympnet(exe, path, outdir, more, args.timeout, cpu=True), gamma)
    if args.skip_peers:
        methods["sindy"] = {"status": "skipped"}
        methods["oracle"] = {"status": "skipped"}
    else:
        t0, c0 = time.monotonic(), time.process_time()
        try:
            g, extra_s = sindy(files, info["d"])
            res = {"status": "ok" if math.isfinite(g) else "failed", "gamma_hat": g,
                   "identified": True, "ci_low": None, "ci_high": None, "extra": extra_s}
        except Interrupted:
            raise
        except Exception as e:  # a peer that breaks on a case is a failure of that peer
            res = {"status": "failed", "reason": f"{type(e).__name__}: {e}"}
        res["seconds"] = time.monotonic() - t0
        res["cpu_seconds"] = time.process_time() - c0
        methods["sindy"] = scorer(res, gamma)
        t0, c0 = time.monotonic(), time.process_time()
        try:
            o = oracle(files, info, s, np.random.default_rng(case["seed"] + [1]))
            res = {"status": "ok" if math.isfinite(o["gamma_hat"]) else "failed", "identified": True,
                   **o}
        except Interrupted:
            raise
        except Exception as e:
            res = {"status": "failed", "reason": f"{type(e).__name__}: {e}"}
        res["seconds"] = time.monotonic() - t0
        res["cpu_seconds"] = time.process_time() - c0
        methods["oracle"] = scorer(res, gamma)
    if args.only_peers:
        methods["csympnet"] = {"status": "skipped"}
        if args.library:
            methods["csympnet_library"] = {"status": "skipped"}
    else:
        outdir = os.path.join(cdir, "csympnet")
        if os.path.isdir(outdir):
            shutil.rmtree(outdir)
        case["paths"]["csympnet_out"] = os.path.relpath(outdir, args.out)
        methods["csympnet"] = scorer(run_csympnet(exe, data, outdir, extra, args.timeout, cpu=True),
                                     gamma)
        if args.library and info["d"] > LIBRARY_MAX_D:
            methods["csympnet_library"] = {"status": "skipped"}
        elif args.library:  # the same data, the Hamiltonian-library core forced
            outdir = os.path.join(cdir, "csympnet_library")
            if os.path.isdir(outdir):
                shutil.rmtree(outdir)
            case["paths"]["csympnet_library_out"] = os.path.relpath(outdir, args.out)
            methods["csympnet_library"] = scorer(
                run_csympnet(exe, data, outdir, ["--core", "library"] + extra, args.timeout),
                gamma)
    case["methods"] = methods
    return case
