"""One case of the forced plan (--forced-plan): the records (idbench.forced), their CSV files,
and every method on them in one run -- linear ARX, polynomial NARX, the oracle (multiple
shooting of the true form) and csympnet -- with each method's CPU seconds.

    arx       peers/arx.py: least squares, orders by AIC; no gamma
    narx      peers/narx.py: FROLS term selection, structure by validation free-run error; no gamma
    oracle    peers/forced_oracle.py: the true form by multiple shooting, gamma with a 95%
              interval, started at gamma_true exp(0.2 z) (z standard normal clipped to +-2, drawn
              from the case's seed + [1])
    csympnet  `csympnet fit train.csv --out DIR -q --no-figures`, then `csympnet evaluate --model
              DIR/model.json --data TEST.csv --warmup 100 --out DIR/evaluate-<test>` per test
              record; gamma_hat, gamma_ci_low/high from DIR/report.json, the free-run RMS from
              the evaluation's report.json "simulation": {"rmse": [...]}. A binary that refuses
              the input columns gives status "unsupported" (the error's last line as the reason);
              the peers run all the same.

Every test record is scored by the free-run RMS per output after a warm-up of WARMUP = 100
samples (the start: measured lags for ARX/NARX, a least-squares start state for the oracle,
csympnet evaluate's own --warmup fit), against the record's noisy positions ("rms", as csympnet
evaluate scores) and, for the Python peers, against the noise-free ones ("rms_clean"). A free
run that leaves 1000 times the training range is "diverged" (its RMS counts as infinite in the
medians). CPU seconds: process_time for the Python peers (exact with --jobs 1), wait4 of the
children for csympnet (fit and evaluations).
"""
import math
import os
import shutil
import time

import numpy as np

from .common import Interrupted, check_stop
from .forced import generate_forced, write_forced_csv
from .peers.arx import WARMUP, arx_peer
from .peers.csympnet import run_csympnet_forced
from .peers.forced_oracle import oracle_peer
from .peers.narx import narx_peer
from .runner import score

FORCED_METHODS = ["csympnet", "oracle", "narx", "arx"]


def _timed(fn):
    t0, c0 = time.monotonic(), time.process_time()
    try:
        r = fn()
        ok = r.get("gamma_hat") is None or math.isfinite(r["gamma_hat"])
        res = {"status": "ok" if ok else "failed", "identified": r.get("gamma_hat") is not None,
               **r}
    except Interrupted:
        raise
    except Exception as e:  # a peer that breaks on a case is a failure of that peer
        res = {"status": "failed", "reason": f"{type(e).__name__}: {e}", "tests": {}}
    res["seconds"] = time.monotonic() - t0
    res["cpu_seconds"] = time.process_time() - c0
    return res


def run_forced_case(case, args, exe, extra):
    check_stop()
    cdir = os.path.join(args.out, "cases", case["id"])
    os.makedirs(cdir, exist_ok=True)
    t0 = time.monotonic()
    records, info, s = generate_forced(case, args.quick)
    case.update(info)
    case["generate_seconds"] = time.monotonic() - t0
    case["paths"] = {}
    for name, r in records.items():
        path = os.path.join(cdir, f"{name}.csv")
        write_forced_csv(path, r["t"], r["q"], r["u"])
        case["paths"][name] = os.path.relpath(path, args.out)
    gamma = info["gamma_true"]
    rng = np.random.default_rng(case["seed"] + [1])
    g_start = gamma * math.exp(0.2 * float(np.clip(rng.standard_normal(), -2, 2)))
    methods = {"oracle": _timed(lambda: oracle_peer(s, records, g_start)),
               "narx": _timed(lambda: narx_peer(records)),
               "arx": _timed(lambda: arx_peer(records))}
    if args.only_peers:
        methods["csympnet"] = {"status": "skipped", "tests": {}}
    else:
        outdir = os.path.join(cdir, "csympnet")
        if os.path.isdir(outdir):
            shutil.rmtree(outdir)
        case["paths"]["csympnet_out"] = os.path.relpath(outdir, args.out)
        tests = {k: os.path.join(args.out, p) for k, p in case["paths"].items()
                 if k.startswith("test-")}
        methods["csympnet"] = run_csympnet_forced(exe, os.path.join(args.out,
                                                                    case["paths"]["train"]),
                                                  tests, outdir, extra, args.timeout, WARMUP)
    for r in methods.values():
        if r.get("gamma_hat") is not None:
            score(r, gamma)
    case["methods"] = {m: methods[m] for m in FORCED_METHODS if m in methods}
    return case
