"""The polynomial NARX peer of the forced plan: forward orthogonal least squares (term selection
by the error reduction ratio, ERR) on a polynomial of lagged outputs and inputs, simulated free
run (fed its own outputs).

    y_t = sum_l c_l prod(v_t over the l-th term's factors),
    v_t = (y_{t-1}, ..., y_{t-ny}, u_t, ..., u_{t-nu+1})   (all outputs, all inputs)

The candidate terms are every monomial of degree 0..deg in v_t (the constant included); y and
u are divided by their training standard deviations first (a scale, no shift: the constant
term carries offsets). Each output has its own terms: FROLS orders the candidates by ERR (the
share of the output's energy the term's orthogonalised part explains, the largest first) on the
first 70% of the training record (estimation part). The structure -- ny, nu in {2, 3}, deg in
{2, 3} and the number k of terms per output (the first k in ERR order; k on a grid up to 40) --
is chosen by the free-run simulation RMS on the last 30% of the training record (validation
part; its first WARMUP samples measured, as on the tests): among the choices within 2% of the
smallest validation RMS, the one with the fewest terms. The selected terms' coefficients are
then estimated again by least squares on the whole training record. No gamma.
"""
import itertools
import math

import numpy as np

from ..common import check_stop
from .arx import DIVERGED, WARMUP, free_run

NY = (2, 3)
NU = (2, 3)
DEGREES = (2, 3)
K_GRID = (1, 2, 3, 4, 5, 6, 8, 10, 13, 16, 20, 25, 30, 40)
ESTIMATION_SHARE = 0.7
TIE = 1.02


def candidate_terms(nv, deg):
    """(M, deg) indices into [1, v_1..v_nv] (0: the factor 1): every monomial of degree <= deg"""
    return np.array(list(itertools.combinations_with_replacement(range(nv + 1), deg)),
                    dtype=int)


def variables(ys, us, ny, nu, start):
    """rows t = start..n-1 of [1, y_{t-1..t-ny}, u_{t..t-nu+1}] (scaled data)"""
    n = ys.shape[0]
    cols = [np.ones((n - start, 1))]
    cols += [ys[start - i:n - i] for i in range(1, ny + 1)]
    cols += [us[start - j:n - j] for j in range(nu)]
    return np.concatenate(cols, axis=1)


def monomials(V, T):
    """V (N, 1 + nv), T (M, deg) -> (N, M)"""
    out = V[:, T[:, 0]].copy()
    for j in range(1, T.shape[1]):
        out *= V[:, T[:, j]]
    return out


def frols(P, y, kmax):
    """forward orthogonal least squares: the first kmax columns of P in ERR order, and their
    ERR values"""
    Q = P.astype(float, copy=True)
    yy = float(y @ y)
    chosen, errs = [], []
    alive = np.ones(P.shape[1], bool)
    norms0 = np.einsum("ij,ij->j", P, P)
    for _ in range(min(kmax, P.shape[1])):
        nn = np.einsum("ij,ij->j", Q, Q)
        ok = alive & (nn > 1e-10 * np.maximum(norms0, 1e-300))
        if not ok.any():
            break
        g = Q.T @ y
        err = np.where(ok, g * g / np.where(ok, nn, 1.0) / yy, -1.0)
        j = int(np.argmax(err))
        chosen.append(j)
        errs.append(float(err[j]))
        alive[j] = False
        w = Q[:, j].copy()
        Q -= np.outer(w, (w @ Q) / (w @ w))
    return chosen, errs


def simulate_narx(model, y, u, warmup):
    """free run from sample `warmup`; None if it diverged"""
    ys = np.asarray(y, float) / model["sy"]
    us = np.asarray(u, float) / model["su"]
    ny, nu, d = model["ny"], model["nu"], ys.shape[1]
    out = ys.copy()
    limit = DIVERGED * model["y_range"]
    terms, coefs = model["terms"], model["coefs"]
    for t in range(max(warmup, ny, nu - 1), ys.shape[0]):
        v = np.concatenate([[1.0], out[t - ny:t][::-1].ravel(), us[t - nu + 1:t + 1][::-1].ravel()])
        for i in range(d):
            T = terms[i]
            mono = v[T[:, 0]]
            for j in range(1, T.shape[1]):
                mono = mono * v[T[:, j]]
            out[t, i] = coefs[i] @ mono
        if not np.all(np.abs(out[t]) < limit):
            return None
    return out * model["sy"]


def _fit_terms(ys, us, ny, nu, T_out, start):
    V = variables(ys, us, ny, nu, start)
    coefs = []
    for i, T in enumerate(T_out):
        c, *_ = np.linalg.lstsq(monomials(V, T), ys[start:, i], rcond=None)
        coefs.append(c)
    return coefs


def fit_narx(y, u, ny_grid=NY, nu_grid=NU, degrees=DEGREES, k_grid=K_GRID, warmup=WARMUP):
    y = np.asarray(y, float)
    u = np.asarray(u, float)
    sy = np.where(y.std(axis=0) > 0, y.std(axis=0), 1.0)
    su = np.where(u.std(axis=0) > 0, u.std(axis=0), 1.0)
    ys, us = y / sy, u / su
    d = y.shape[1]
    n_est = int(ESTIMATION_SHARE * y.shape[0])
    val = {"q": y[n_est:], "u": u[n_est:], "q_clean": y[n_est:]}
    y_range = float(np.abs(ys).max())
    start = max(max(ny_grid), max(nu_grid) - 1)
    tried = []
    for ny, nu, deg in itertools.product(ny_grid, nu_grid, degrees):
        check_stop()
        T = candidate_terms(ny * d + nu * us.shape[1], deg)
        P = monomials(variables(ys[:n_est], us[:n_est], ny, nu, start), T)
        orders = [frols(P, ys[start:n_est, i], max(k_grid))[0] for i in range(d)]
        for k in k_grid:
            if k > min(len(o) for o in orders):
                continue
            T_out = [T[o[:k]] for o in orders]
            coefs = _fit_terms(ys[:n_est], us[:n_est], ny, nu, T_out, start)
            model = {"ny": ny, "nu": nu, "deg": deg, "k": k, "terms": T_out, "coefs": coefs,
                     "sy": sy, "su": su, "y_range": y_range}
            r = free_run(simulate_narx, model, val, warmup)
            rms = math.inf if r["diverged"] else float(np.sqrt(np.mean(
                np.square(np.asarray(r["rms"]) / sy))))
            tried.append((rms, k * d, deg, model))
    best = min(t[0] for t in tried)
    if not math.isfinite(best):
        raise RuntimeError("every NARX structure diverged on the validation part")
    rms, _, _, model = min((t for t in tried if t[0] <= TIE * best),
                           key=lambda t: (t[1], t[2], t[0]))
    model["coefs"] = _fit_terms(ys, us, model["ny"], model["nu"], model["terms"], start)
    model["validation_rms"] = rms
    return model


def term_names(model, d, m):
    names = ["1"] + [f"y{i + 1}(t-{l})" for l in range(1, model["ny"] + 1) for i in range(d)] \
        + [f"u{j + 1}(t-{l})" if l else f"u{j + 1}(t)" for l in range(model["nu"])
           for j in range(m)]
    return [["*".join(names[i] for i in row if i) or "1" for row in T] for T in model["terms"]]


def narx_peer(records):
    tr = records["train"]
    model = fit_narx(tr["q"], tr["u"])
    tests = {k: free_run(simulate_narx, model, r) for k, r in records.items() if k != "train"}
    return {"gamma_hat": None, "ci_low": None, "ci_high": None, "tests": tests,
            "extra": {"ny": model["ny"], "nu": model["nu"], "degree": model["deg"],
                      "terms_per_output": model["k"], "validation_rms": model["validation_rms"],
                      "terms": term_names(model, tr["q"].shape[1], tr["u"].shape[1])}}
