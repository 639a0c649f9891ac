"""The linear ARX peer of the forced plan, and the free-run scoring every peer shares.

    y_t = c + sum_{i=1..na} A_i y_{t-i} + sum_{j=0..nb-1} B_j u_{t-j} + e_t

(MIMO: y of d outputs, u of m inputs, A_i d x d, B_j d x m; the current input u_t is a
regressor because a first-order hold makes the sampled system proper but not strictly proper.)
Least squares, one regression per output on the same regressors; the orders (na, nb) in
1..6 x 1..6 chosen by AIC on the training record, N log det(E^T E / N) + 2 (number of
coefficients), every order pair fitted on the same rows (those after the largest lag).

Free-run simulation (`free_run`): the first `warmup` samples of a test record are the measured
outputs (the start: the lags the simulation begins from) and are left out of the score; from
there on the model is fed its own outputs. rms: per output, over the samples after the warm-up.
"""
import itertools
import math

import numpy as np

from ..common import check_stop
from ..forced import WARMUP_SAMPLES

WARMUP = WARMUP_SAMPLES  # samples of every test record used for the start, not scored (100)
ORDERS = range(1, 7)  # na, nb tried by AIC
DIVERGED = 1e3        # a free run is stopped (diverged) beyond this many times the training range


def regressors(y, u, na, nb, start):
    """rows t = start..n-1: [1, y_{t-1}, ..., y_{t-na}, u_t, ..., u_{t-nb+1}]"""
    n = y.shape[0]
    cols = [np.ones((n - start, 1))]
    cols += [y[start - i:n - i] for i in range(1, na + 1)]
    cols += [u[start - j:n - j] for j in range(nb)]
    return np.concatenate(cols, axis=1)


def fit_arx(y, u, orders=ORDERS):
    """y (n, d), u (n, m) of the training record. Returns the model dict."""
    y = np.asarray(y, float)
    u = np.asarray(u, float)
    start = max(orders)
    target = y[start:]
    N, d = target.shape
    best = None
    for na, nb in itertools.product(orders, orders):
        check_stop()
        X = regressors(y, u, na, nb, start)
        coef, *_ = np.linalg.lstsq(X, target, rcond=None)
        E = target - X @ coef
        sign, logdet = np.linalg.slogdet(E.T @ E / N)
        aic = N * logdet + 2 * coef.size if sign > 0 else -math.inf
        if best is None or aic < best["aic"]:
            best = {"na": na, "nb": nb, "coef": coef, "aic": aic}
    return {"kind": "arx", "na": best["na"], "nb": best["nb"], "coef": best["coef"],
            "aic": best["aic"], "d": d, "m": u.shape[1],
            "y_range": float(np.abs(y).max())}


def simulate_arx(model, y, u, warmup):
    """free run from sample `warmup` (y before it: measured). Returns (n, d), or None if it
    diverged."""
    na, nb, coef = model["na"], model["nb"], model["coef"]
    n = y.shape[0]
    out = np.array(y, float, copy=True)
    A = [coef[1 + (i - 1) * model["d"]:1 + i * model["d"]] for i in range(1, na + 1)]
    off = 1 + na * model["d"]
    Bm = [coef[off + j * model["m"]:off + (j + 1) * model["m"]] for j in range(nb)]
    limit = DIVERGED * model["y_range"]
    for t in range(max(warmup, na, nb - 1), n):
        v = coef[0].copy()
        for i in range(na):
            v += out[t - 1 - i] @ A[i]
        for j in range(nb):
            v += u[t - j] @ Bm[j]
        out[t] = v
        if not np.all(np.abs(v) < limit):
            return None
    return out


def free_run(simulate, model, rec, warmup=WARMUP):
    """score one test record: {"rms": [per output], "rms_clean": [...] (against the
    noise-free positions), "diverged"}"""
    check_stop()
    y, u = rec["q"], rec["u"]
    out = simulate(model, y, u, warmup)
    if out is None:
        return {"rms": None, "rms_clean": None, "diverged": True}
    r = out[warmup:] - y[warmup:]
    rc = out[warmup:] - rec["q_clean"][warmup:]
    return {"rms": np.sqrt((r ** 2).mean(axis=0)).tolist(),
            "rms_clean": np.sqrt((rc ** 2).mean(axis=0)).tolist(), "diverged": False}


def arx_peer(records):
    """fit on records["train"], free run on every test record"""
    m = fit_arx(records["train"]["q"], records["train"]["u"])
    tests = {k: free_run(simulate_arx, m, r) for k, r in records.items() if k != "train"}
    return {"gamma_hat": None, "ci_low": None, "ci_high": None, "tests": tests,
            "extra": {"na": m["na"], "nb": m["nb"], "aic": m["aic"]}}
