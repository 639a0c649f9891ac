"""The oracle on records of positions alone: the true form of the system fitted to the whole
record of positions (a direct output-error fit: one start state, the whole record predicted by
the model, least squares on the positions), in natural units (it is given the true unit scales,
offsets and time scale, as the oracle with momenta is). The potential parameters start at the
truth (a fit of a long record from a wrong frequency lands in a wrong minimum, and the oracle is
the floor, not a competitor), gamma at the truth times exp(0.2 z); the start state by linear
least squares (linear) or from the first samples (nonlinear). Two passes: unweighted, then each
coordinate weighted by its own residual spread. Interval: estimate +- 1.96 standard errors from
the Gauss-Newton covariance scaled by the residual variance.

    linear     chains of unit masses (idbench.linear): parameters the springs k_0..k_d (their
               sum for d = 1), gamma, q(0), q'(0); positions in closed form through the modes
    nonlinear  a d = 1 system of idbench.systems (the pendulum): its potential parameters,
               gamma, q(0), p(0); positions by RK4 over the record (omega_max * substep <= 0.02);
               given measured momenta too, the same fit on q and p (each weighted by its own
               residual spread in the second pass): the whole-record fit of the true form
"""
import math

import numpy as np

from ..common import check_stop
from ..linear import chain_stiffness, modal_basis
from ..simulation import rk4

Z95 = 1.959963984540054


def _interval(res, npar_gamma_index):
    J = res.jac
    dof = max(1, res.fun.size - J.shape[1])
    s2 = float(res.fun @ res.fun) / dof
    cov = s2 * np.linalg.pinv(J.T @ J)
    var = float(cov[npar_gamma_index, npar_gamma_index])
    return math.sqrt(var) if math.isfinite(var) and var >= 0 else None


def _two_passes(resid, x0, d):
    """resid(x, w) -> (n, d) residuals divided by w (d,); least squares unweighted, then
    weighted by each coordinate's residual spread."""
    from scipy.optimize import least_squares  # the main plans need NumPy alone
    w = np.ones(d)
    res = least_squares(lambda x: resid(x, w).ravel(), x0, method="lm", x_scale="jac",
                        xtol=1e-13, ftol=1e-13)
    w = resid(res.x, np.ones(d)).std(axis=0)
    w = np.where(w > 0, w, 1.0)
    res = least_squares(lambda x: resid(x, w).ravel(), res.x, method="lm", x_scale="jac",
                        xtol=1e-13, ftol=1e-13)
    return res, w


def linear(t, q, springs_true, gamma_start):
    """t (n,), q (n, d) natural positions (rest at 0). Returns gamma_hat, ci_low, ci_high."""
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    d = q.shape[1]
    k_true = np.asarray(springs_true, dtype=float)
    nk = 1 if d == 1 else d + 1
    k0 = np.array([k_true.sum()]) if d == 1 else k_true

    def K_of(k):
        return np.array([[k[0]]]) if d == 1 else chain_stiffness(k)

    def predict(x):
        k, g = x[:nk], x[nk]
        a0, b0 = x[nk + 1:nk + 1 + d], x[nk + 1 + d:]
        U, c, s = modal_basis(K_of(k), g, t)
        return (c * (U.T @ a0)[None, :] + s * (U.T @ b0)[None, :]) @ U.T

    # start state: linear least squares at the start parameters
    U, c, s = modal_basis(K_of(k0), gamma_start, t)
    cols = np.concatenate([c[:, None, :] * U[None, :, :], s[:, None, :] * U[None, :, :]], axis=2)
    A = cols.reshape(-1, 2 * d)  # rows (sample, coordinate), columns (modal a0 | b0)
    ab = np.linalg.lstsq(A, q.ravel(), rcond=None)[0]
    a0, b0 = U @ ab[:d], U @ ab[d:]
    x0 = np.concatenate([k0, [gamma_start], a0, b0])

    def resid(x, w):
        check_stop()
        return (predict(x) - q) / w[None, :]
    res, w = _two_passes(resid, x0, d)
    se = _interval(res, nk)
    g = float(res.x[nk])
    return {"gamma_hat": g, "ci_low": None if se is None else g - Z95 * se,
            "ci_high": None if se is None else g + Z95 * se,
            "extra": {"springs_hat": res.x[:nk].tolist(), "gamma_start": float(gamma_start),
                      "residual_sd": w.tolist(), "evaluations": int(res.nfev),
                      "status": int(res.status)}}


def _rollout(s, theta_cols, gamma_cols, q0, p0, t, omega):
    """Positions at times t (n,) of one d = 1 system, one column per parameter set."""
    substep = 0.02 / omega
    q, p = q0[None, :], p0[None, :]
    out = np.empty((t.size, 2, q0.size))
    out[0] = q[0], p[0]
    for i in range(1, t.size):
        if i % 64 == 0:
            check_stop()
        h = t[i] - t[i - 1]
        n = max(1, int(math.ceil(h / substep)))
        q, p = rk4(s["grad"], theta_cols, None, gamma_cols, q, p, h / n, n)
        out[i] = q[0], p[0]
    return out


def nonlinear(t, q, s, gamma_start, p=None):
    """t (n,), q (n,) natural positions of a d = 1 system s (and p (n,) its momenta, when
    measured). Returns gamma_hat, ci_low, ci_high."""
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float).ravel()
    obs = q[:, None] if p is None else np.column_stack([q, np.asarray(p, dtype=float).ravel()])
    nout = obs.shape[1]
    nth = len(s["theta"])
    th0 = np.asarray(s["theta"], dtype=float)
    n0 = min(5, q.size - 1)
    p_start = (q[n0] - q[0]) / (t[n0] - t[0]) if p is None else float(p[0])
    x0 = np.concatenate([th0, [gamma_start, q[0], p_start]])

    def columns(X):
        th = [X[:, j] for j in range(nth)]
        Y = _rollout(s, th, X[:, nth], X[:, nth + 1], X[:, nth + 2], t, s["omega_max"])
        return Y[:, :nout, :].reshape(t.size * nout, -1)  # rows (sample, output)

    cache = {}

    def fun_and_jac(x, w):
        key = x.tobytes()
        if key not in cache:
            eps = 1e-6 * np.maximum(np.abs(x), 1e-3)
            X = np.tile(x, (1 + 2 * x.size, 1))
            for j in range(x.size):
                X[1 + 2 * j, j] += eps[j]
                X[2 + 2 * j, j] -= eps[j]
            Y = columns(X)
            J = (Y[:, 1::2] - Y[:, 2::2]) / (2 * eps[None, :])
            cache.clear()
            cache[key] = (Y[:, 0], J)
        y, J = cache[key]
        wr = np.tile(w, t.size)
        return (y - obs.ravel()) / wr, J / wr[:, None]

    def run(x, w):
        from scipy.optimize import least_squares
        return least_squares(lambda x: fun_and_jac(x, w)[0], x, jac=lambda x: fun_and_jac(x, w)[1],
                             method="lm", x_scale="jac", xtol=1e-12, ftol=1e-12)
    res = run(x0, np.ones(nout))
    if nout > 1:  # second pass: each output weighted by its own residual spread
        w = res.fun.reshape(t.size, nout).std(axis=0)
        res = run(res.x, np.where(w > 0, w, 1.0))
    se = _interval(res, nth)
    g = float(res.x[nth])
    return {"gamma_hat": g, "ci_low": None if se is None else g - Z95 * se,
            "ci_high": None if se is None else g + Z95 * se,
            "extra": {"theta_hat": res.x[:nth].tolist(), "gamma_start": float(gamma_start),
                      "residual_sd": float(np.std(res.fun)), "evaluations": int(res.nfev),
                      "status": int(res.status)}}
