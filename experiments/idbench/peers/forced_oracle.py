"""The oracle of the forced plan: the true form (the potential's form, gamma, the free entries of
B unknown) fitted by multiple shooting to the positions of the training record, with the known
input held first-order between samples (idbench.forced.simulate, the generator's RK4).

Multiple shooting: the record is cut into segments of SEGMENT samples, each with its own start
state (q, p); the parameters are the globals (potential parameters, gamma, B) and every
segment's start. Residuals: the model's positions minus the measured ones, each sample once
(divided by a per-coordinate weight), and the continuity of each segment's end with the next
one's start (times c/weight for q, c/(weight omega_max) for p). Two Levenberg-Marquardt passes:
unit weights and c = 10, then each coordinate weighted by its residual spread and c = 1e3 (the
segments then join within a thousandth of the noise: the whole-record output-error fit).
Jacobian by central differences, every segment and every perturbation integrated at once as
columns. Start: potential parameters and B at the truth, gamma at the truth times exp(0.2 z)
(the oracle is the floor, not a competitor); segment starts: the measured q, and p from
centred differences of it.

Interval: gamma_hat +- 1.96 standard errors, the Gauss-Newton covariance s^2 (J^T J)^+ with
s^2 the weighted position residuals' sum of squares over (samples x d - globals - 2 d).

Tests: the start state fitted to the first WARMUP samples (least squares over (q0, p0), the
parameters fixed), the record simulated from it; the score after the warm-up (peers/arx.py).
"""
import math

import numpy as np

from ..common import check_stop
from ..forced import simulate
from .arx import WARMUP, free_run

SEGMENT = 64
ORACLE_OMEGA_SUBSTEP = 0.05
Z95 = 1.959963984540054


def _globals_of(s):
    return list(s["theta"]) + [None] + [float(s["B"][i, j]) for i, j in s["b_free"]]


def _substeps(s, h, qmax):
    w = s["omega_max"] * (math.sqrt(1.0 + 3.0 * qmax * qmax) if s["name"] != "pendulum" else 1.0)
    return max(1, int(math.ceil(h * w / ORACLE_OMEGA_SUBSTEP)))


def rollout(s, G, q0, p0, U, h, substeps):
    """G (ncols, ng) parameter sets, q0, p0 (d, ncols), U (n, m, ncols) inputs at the samples.
    Returns Q, P (n, d, ncols)."""
    nth = len(s["theta"])
    th = [G[:, i] for i in range(nth)]
    gamma = G[:, nth]
    Bc = np.zeros((s["d"], s["m"], G.shape[0]))
    for k, (i, j) in enumerate(s["b_free"]):
        Bc[i, j] = G[:, nth + 1 + k]
    force = np.einsum("dmc,nmc->ndc", Bc, U)
    return simulate(lambda q, p: -s["grad"](q, th) - gamma * p, q0, p0, force, h, substeps)


class _Shooting:
    def __init__(self, s, q, u, h, substeps, L=SEGMENT):
        self.s, self.h, self.sub = s, h, substeps
        n, d = q.shape
        self.n, self.d, self.L = n, d, L
        self.S = S = max(1, int(math.ceil((n - 1) / L)))
        self.ng = len(s["theta"]) + 1 + len(s["b_free"])
        pad = S * L + 1
        qp = np.zeros((pad, d))
        qp[:n] = q
        up = np.zeros((pad, u.shape[1]))
        up[:n] = u
        idx = np.arange(L + 1)[:, None] + L * np.arange(S)[None, :]      # (L+1, S)
        self.obs = qp[idx].transpose(0, 2, 1)                            # (L+1, d, S)
        self.U = up[idx].transpose(0, 2, 1)                              # (L+1, m, S)
        last = n - 1 - (S - 1) * L
        valid = np.zeros((L + 1, S), bool)
        valid[:L, :S - 1] = True
        valid[:last + 1, S - 1] = True
        self.valid = valid
        self.w = np.ones(d)
        self.c = 10.0

    def split(self, x):
        st = x[self.ng:].reshape(self.S, 2 * self.d)
        return x[:self.ng], st[:, :self.d].T, st[:, self.d:].T

    def _roll(self, G, q0, p0, reps):
        U = np.tile(self.U, (1, 1, reps))
        return rollout(self.s, G, q0, p0, U, self.h, self.sub)

    def _resid(self, Q, P, q0n, p0n):
        rp = ((Q - self.obs) / self.w[None, :, None]).transpose(0, 2, 1)[self.valid]
        cq = self.c * (Q[self.L, :, :-1] - q0n[:, 1:]) / self.w[:, None]
        cp = self.c * (P[self.L, :, :-1] - p0n[:, 1:]) / (self.w[:, None] * self.s["omega_max"])
        return np.concatenate([rp.ravel(), cq.T.ravel(), cp.T.ravel()])

    def fun(self, x):
        check_stop()
        g, q0, p0 = self.split(x)
        Q, P = self._roll(np.tile(g, (self.S, 1)), q0, p0, 1)
        return self._resid(Q, P, q0, p0)

    def jac(self, x):
        check_stop()
        g, q0, p0 = self.split(x)
        ng, d, S, L = self.ng, self.d, self.S, self.L
        C = 1 + 2 * ng + 4 * d
        eg = 1e-6 * np.maximum(np.abs(g), 1e-3)
        es = 1e-6 * max(float(np.abs(self.obs).max()), 1e-3)
        G = np.tile(g, (C * S, 1))
        Q0 = np.tile(q0, (1, C))
        P0 = np.tile(p0, (1, C))
        for i in range(ng):
            G[(1 + 2 * i) * S:(2 + 2 * i) * S, i] += eg[i]
            G[(2 + 2 * i) * S:(3 + 2 * i) * S, i] -= eg[i]
        for k in range(2 * d):
            A = Q0 if k < d else P0
            v = 1 + 2 * ng + 2 * k
            A[k % d, v * S:(v + 1) * S] += es
            A[k % d, (v + 1) * S:(v + 2) * S] -= es
        Q, P = self._roll(G, Q0, P0, C)
        Q = Q.reshape(L + 1, d, C, S)
        P = P.reshape(L + 1, d, C, S)
        cols = ng + 2 * d * S
        dQ = np.zeros((L + 1, d, S, cols))
        dP = np.zeros((L + 1, d, S, cols))
        for i in range(ng):
            dQ[..., i] = (Q[:, :, 1 + 2 * i] - Q[:, :, 2 + 2 * i]) / (2 * eg[i])
            dP[..., i] = (P[:, :, 1 + 2 * i] - P[:, :, 2 + 2 * i]) / (2 * eg[i])
        seg = np.arange(S)
        for k in range(2 * d):
            v = 1 + 2 * ng + 2 * k
            dQ[:, :, seg, ng + 2 * d * seg + k] = (Q[:, :, v] - Q[:, :, v + 1]) / (2 * es)
            dP[:, :, seg, ng + 2 * d * seg + k] = (P[:, :, v] - P[:, :, v + 1]) / (2 * es)
        Jp = (dQ / self.w[None, :, None, None]).transpose(0, 2, 1, 3)[self.valid]
        Jp = Jp.reshape(-1, cols)
        Jc = []
        for A, scale, off in ((dQ, self.w, 0), (dP, self.w * self.s["omega_max"], d)):
            J = self.c * A[L, :, :-1, :].transpose(1, 0, 2) / scale[None, :, None]  # (S-1, d, c)
            for j in range(S - 1):
                J[j, np.arange(d), ng + 2 * d * (j + 1) + off + np.arange(d)] -= \
                    self.c / scale
            Jc.append(J.reshape(-1, cols))
        return np.concatenate([Jp] + Jc, axis=0)


def _least_squares(fun, jac, x0):
    from scipy.optimize import least_squares  # the main plans need NumPy alone
    return least_squares(fun, x0, jac=jac, method="lm", x_scale="jac", xtol=1e-12, ftol=1e-12,
                         max_nfev=200)


def fit(s, t, q, u, gamma_start):
    """s: forced_system; t (n,), q (n, d) noisy positions, u (n, m). Returns dict."""
    q = np.asarray(q, float)
    u = np.asarray(u, float)
    h = float(t[1] - t[0])
    sub = _substeps(s, h, float(np.abs(q).max()))
    sh = _Shooting(s, q, u, h, sub)
    g0 = np.array([gamma_start if v is None else v for v in _globals_of(s)])
    starts = np.arange(sh.S) * sh.L
    v = np.gradient(q, h, axis=0)
    x0 = np.concatenate([g0, np.concatenate([q[starts], v[starts]], axis=1).ravel()])
    res = _least_squares(sh.fun, sh.jac, x0)
    n_res = int(sh.valid.sum()) * sh.d
    r = res.fun[:n_res].reshape(-1, sh.d)
    sh.w = np.where(r.std(axis=0) > 0, r.std(axis=0), 1.0)
    sh.c = 1e3
    res = _least_squares(sh.fun, sh.jac, res.x)
    J = sh.jac(res.x)
    rp = res.fun[:n_res]
    dof = max(1, n_res - sh.ng - 2 * sh.d)
    s2 = float(rp @ rp) / dof
    cov = s2 * np.linalg.pinv(J.T @ J, rcond=1e-13)
    nth = len(s["theta"])
    se = np.sqrt(np.maximum(np.diag(cov)[:sh.ng], 0.0))
    g = res.x[:sh.ng]
    cont = np.abs(res.fun[n_res:]).max() / sh.c if res.fun.size > n_res else 0.0
    return {"globals": g, "se": se, "nth": nth, "substeps": sub,
            "gamma_hat": float(g[nth]), "ci_low": float(g[nth] - Z95 * se[nth]),
            "ci_high": float(g[nth] + Z95 * se[nth]),
            "extra": {"theta_hat": g[:nth].tolist(), "B_hat": g[nth + 1:].tolist(),
                      "B_se": se[nth + 1:].tolist(), "gamma_start": float(gamma_start),
                      "segments": sh.S, "residual_sd": sh.w.tolist(),
                      "continuity_max_over_sd": float(cont), "evaluations": int(res.nfev),
                      "status": int(res.status)}}


def simulate_fitted(s, g, sub, h):
    """the simulate(model, y, u, warmup) of free_run for the fitted globals g"""
    def run(model, y, u, warmup):
        y = np.asarray(y, float)
        d = y.shape[1]
        G = np.tile(g, (1 + 4 * d, 1))
        Uw = np.repeat(u[:warmup, :, None], 1 + 4 * d, axis=2)
        obs = y[:warmup]

        def roll_w(x, cols):
            return rollout(s, G[:cols], x[:d].reshape(d, -1), x[d:].reshape(d, -1),
                           Uw[:, :, :cols], h, sub)[0]

        def fun(x):
            return (roll_w(x[:, None], 1)[:, :, 0] - obs).ravel()

        def jac(x):
            e = 1e-6 * max(float(np.abs(obs).max()), 1e-3)
            X = np.tile(x[:, None], (1, 1 + 4 * d))
            for k in range(2 * d):
                X[k, 1 + 2 * k] += e
                X[k, 2 + 2 * k] -= e
            Q = roll_w(X, 1 + 4 * d)
            return np.stack([(Q[:, :, 1 + 2 * k] - Q[:, :, 2 + 2 * k]).ravel() / (2 * e)
                             for k in range(2 * d)], axis=1)
        x0 = np.concatenate([y[0], np.gradient(y[:5], h, axis=0)[0]])
        x = _least_squares(fun, jac, x0).x
        U = u[:, :, None]
        Q, _ = rollout(s, g[None, :], x[:d, None], x[d:, None], U, h, sub)
        out = Q[:, :, 0]
        if not np.all(np.isfinite(out)):
            return None
        return out
    return run


def oracle_peer(s, records, gamma_start):
    tr = records["train"]
    f = fit(s, tr["t"], tr["q"], tr["u"], gamma_start)
    h = float(tr["t"][1] - tr["t"][0])
    tests = {}
    for k, r in records.items():
        if k == "train":
            continue
        sub = _substeps(s, h, float(np.abs(r["q"]).max()))
        tests[k] = free_run(simulate_fitted(s, f["globals"], sub, h), None, r, WARMUP)
    return {"gamma_hat": f["gamma_hat"], "ci_low": f["ci_low"], "ci_high": f["ci_high"],
            "tests": tests, "extra": f["extra"]}
