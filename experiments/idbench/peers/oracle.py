"""The parametric oracle on records with momenta: the true form fitted to one-step predictions."""
import math

import numpy as np

from ..common import check_stop
from ..simulation import inverse_masses, rk4, rk4_field

ORACLE_OMEGA_DT = 1e-2   # omega_max * RK4 substep inside the oracle's one-step predictions

# ----------------------------------------------------------------------------------------------
# Peer 2: parametric oracle (true form, natural units)


def oracle(files, info, s, rng):
    d = info["d"]
    u = info["units"]
    off = np.asarray(u["q_offset"])
    pairs0, pairs1, hs = [], [], []
    for t, z in files:
        tn = np.asarray(t) / u["time_scale"]
        zn = np.concatenate([(z[:, :d] - off) / u["s_q"], z[:, d:] / u["s_p"]], axis=1)
        pairs0.append(zn[:-1])
        pairs1.append(zn[1:])
        hs.append(np.diff(tn))
    z0 = np.concatenate(pairs0).T
    z1 = np.concatenate(pairs1).T
    h = np.concatenate(hs)
    allz = np.concatenate([np.concatenate([a, b[-1:]]) for a, b in zip(pairs0, pairs1)])
    w = allz.std(axis=0)
    w = np.where(w > 0, w, 1.0)[:, None]
    omega = info["omega_max"]
    substep = ORACLE_OMEGA_DT / omega
    n_sub = max(1, int(math.ceil(float(h.max()) / substep)))
    dt = h / n_sub
    minv = inverse_masses(s)
    q0, p0 = z0[:d], z0[d:]
    npar = len(s["theta"]) + 1

    field = s.get("field")

    def residual(x):
        check_stop()
        with np.errstate(all="ignore"):
            if field is not None:
                q, p = rk4_field(field, list(x[:-1]), x[-1], q0, p0, dt, n_sub)
            else:
                q, p = rk4(s["grad"], list(x[:-1]), minv, x[-1], q0, p0, dt, n_sub)
            return ((np.concatenate([q, p]) - z1) / w).ravel()

    theta_true = np.asarray(s["theta"], dtype=float)
    x0 = np.concatenate([theta_true * np.exp(0.2 * np.clip(rng.standard_normal(len(theta_true)),
                                                           -2, 2)), [0.05 * omega]])
    floor = 1e-3 * np.abs(x0)
    x = x0.copy()
    r = residual(x)
    cost = float(r @ r)
    if not math.isfinite(cost):
        raise RuntimeError("oracle: the starting point does not integrate")
    def jacobian(x):
        """central differences, steps relative to each parameter"""
        eps = 1e-6 * np.maximum(np.abs(x), floor)
        J = np.empty((r.size, npar))
        for j in range(npar):
            e = np.zeros(npar)
            e[j] = eps[j]
            J[:, j] = (residual(x + e) - residual(x - e)) / (2 * eps[j])
        return J

    lam = 1e-3
    iters = 0
    for iters in range(1, 101):
        J = jacobian(x)
        A = J.T @ J
        g = J.T @ r
        dA = np.diag(A).copy()
        dA[dA == 0] = 1.0
        improved = False
        while lam < 1e16:
            try:
                step = np.linalg.solve(A + lam * np.diag(dA), -g)
            except np.linalg.LinAlgError:
                lam *= 10
                continue
            xn = x + step
            rn = residual(xn)
            cn = float(rn @ rn)
            if math.isfinite(cn) and cn < cost:
                improved = True
                break
            lam *= 10
        if not improved:
            break
        rel_step = float(np.max(np.abs(step) / np.maximum(np.abs(xn), floor)))
        drop = cost - cn
        x, r, cost = xn, rn, cn
        lam = max(lam / 10, 1e-15)
        if rel_step < 1e-12 or drop <= 1e-15 * cost:
            break
    J = jacobian(x)
    s2 = cost / max(1, r.size - npar)
    cov = s2 * np.linalg.pinv(J.T @ J)
    var = float(cov[-1, -1])
    se = math.sqrt(var) if math.isfinite(var) and var >= 0 else None
    c = u["time_scale"]
    gamma = float(x[-1])
    return {"gamma_hat": gamma / c,
            "ci_low": None if se is None else (gamma - 1.96 * se) / c,
            "ci_high": None if se is None else (gamma + 1.96 * se) / c,
            "extra": {"theta_hat": [float(v) for v in x[:-1]], "iterations": iters,
                      "residual_rms": math.sqrt(cost / r.size), "substeps_per_step": n_sub,
                      "start": [float(v) for v in x0]}}
