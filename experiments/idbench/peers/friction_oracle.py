"""The friction plan's oracle: the true form of the record's ODE (idbench/friction.py's
simulators, the kind of dissipation known) fitted to the whole record by least squares, with
omega, gamma, the friction or drag rate and every trajectory's start state unknown.

It is given the true units (the encoder's counts per radian and offset) and starts at the
true omega (what a user reads off the spectrum), gamma and the rate at the truth times
exp(0.2 z) (z standard normal clipped to +-2, from the case's seed), the start states at the
first samples (q' from the first difference where p is not given).
Residuals: q, and p where given, each divided by the record's spread of that column (the
noise is a share of the spread). Fitted by scipy.optimize.least_squares (trust region, finite
differences), continued over the first quarter, half and the whole of each trajectory (a
long record's phase makes local minima), the first quarter from the best of three starts
where a rate is fitted (the jittered one, and two that move dissipation between gamma and the
rate: dry friction makes the cost rough along that split); interval: estimate +- 1.96 Gauss-Newton standard errors scaled by the residual
variance. The simulators run with fewer substeps than the records' (drag 8, the pendulum 4 a
sample; the Coulomb oscillator is exact), so the oracle's form is exact to about 1e-7.
"""
import math

import numpy as np

from ..friction import simulate

ORACLE_SUBSTEPS = {"drag": 8, "pendulum-coulomb": 4}


def _trajectories(rec, truth):
    """per trajectory (q in radians, p or None) from the record"""
    out = []
    for j in np.unique(rec["traj"]):
        k = rec["traj"] == j
        q = (rec["q"][k] - truth["offset"]) / truth["scale"]
        p = None if rec["p"] is None else rec["p"][k]
        out.append((q, p))
    return out


def friction_oracle(rec, truth, rng, level_z=1.959963984540054):
    from scipy.optimize import least_squares
    kind = truth["kind"]
    trajs = _trajectories(rec, truth)
    h, points = truth["h"], truth["points"]
    has_rate = kind != "viscous"
    n_model = 3 if has_rate else 2
    jitter = np.exp(0.2 * np.clip(rng.standard_normal(n_model - 1), -2, 2))
    x0 = [truth["omega"], truth["gamma"] * jitter[0]]
    if has_rate:
        x0.append(truth["rate"] * jitter[1])
    for q, p in trajs:
        x0 += [q[0], p[0] if p is not None else (q[1] - q[0]) / h]
    x0 = np.array(x0)
    sd_q = max(float(np.concatenate([q for q, _ in trajs]).std()), 1e-300)
    sd_p = (max(float(np.concatenate([p for _, p in trajs]).std()), 1e-300)
            if trajs[0][1] is not None else None)
    sub = ORACLE_SUBSTEPS.get(kind)

    def residuals(x, upto=points):
        omega, gamma = x[0], x[1]
        rate = x[2] if has_rate else 0.0
        if omega <= 0.5 * abs(gamma) or omega <= 0 or (has_rate and rate < 0):
            return np.full(sum(upto * (1 if p is None else 2) for _, p in trajs), 1e6)
        out = []
        for j, (q, p) in enumerate(trajs):
            q0, v0 = x[n_model + 2 * j], x[n_model + 2 * j + 1]
            z = simulate(kind, omega, gamma, rate, q0, v0, h, upto, substeps=sub)
            out.append((z[:, 0] - q[:upto]) / sd_q)
            if p is not None:
                out.append((z[:, 1] - p[:upto]) / sd_p)
        r = np.concatenate(out)
        return np.where(np.isfinite(r), r, 1e6)

    # A start far from the truth in phase finds a local minimum over a long record: the fit is
    # continued over the first quarter, half and then the whole of each trajectory. Dry
    # friction also makes the cost rough along the split between gamma and mu (a trial that
    # sticks early has no gradient in the rest of the record): on the first quarter, the best
    # of the jittered start and two that move dissipation from one to the other.
    starts = [x0]
    if has_rate:
        for fg, fr in ((1.5, 0.5), (0.5, 1.5)):
            x = x0.copy()
            x[1], x[2] = x0[1] * fg, x0[2] * fr
            starts.append(x)
    fit = None
    for upto in (max(points // 4, 10), max(points // 2, 10), points):
        tried = starts if fit is None else [fit.x]
        best = None
        for x in tried:
            f = least_squares(lambda y: residuals(y, upto), x, method="trf", x_scale="jac",
                              max_nfev=60 * x0.size)
            if best is None or f.cost < best.cost:
                best = f
        fit = best
    r = fit.fun
    dof = max(r.size - x0.size, 1)
    s2 = float(r @ r) / dof
    try:
        cov = s2 * np.linalg.inv(fit.jac.T @ fit.jac)
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        se = np.full(x0.size, np.nan)
    g, g_se = float(fit.x[1]), float(se[1])
    res = {"gamma_hat": g, "ci_low": g - level_z * g_se, "ci_high": g + level_z * g_se,
           "extra": {"omega": float(fit.x[0]), "nfev": int(fit.nfev),
                     "status": int(fit.status), "residual_sd": math.sqrt(s2)}}
    if has_rate:
        # the rate in the record's units (mu scales with the unit, c inversely)
        unit = truth["scale"] if kind != "drag" else 1.0 / truth["scale"]
        m, m_se = float(fit.x[2]) * unit, float(se[2]) * unit
        res["rate"] = {"kind": "drag" if kind == "drag" else "coulomb", "value": m,
                       "low": m - level_z * m_se, "high": m + level_z * m_se}
    return res
