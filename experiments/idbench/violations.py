"""Violation cases: right-hand sides that break one assumption of the model class."""
import math

import numpy as np

from .simulation import integrate
from .systems import DEFAULT_SYSTEMS

# ----------------------------------------------------------------------------------------------
# Violation cases: data that break one assumption of the model class


D1_SYSTEMS = ["pendulum", "duffing", "morse", "linear"]
# DEFAULT_SYSTEMS only: the violation right-hand sides are written as dq/dt = M^-1 p,
# dp/dt = f(t, q, p) (grad V, linear modes), which a field system (double-pendulum) lacks.
VIOLATION_SYSTEMS = {
    "nonuniform": ["toda", "fpu-alpha", "fpu-beta", "henon-heiles", "coupled-pendulums"],
    "coulomb": D1_SYSTEMS,
    "quadratic-drag": D1_SYSTEMS,
    "periodic-force": DEFAULT_SYSTEMS,
    "drifting-equilibrium": [x for x in DEFAULT_SYSTEMS if x != "softened-central"],
    "energy-gain": DEFAULT_SYSTEMS,
}

# V(q) - min V for the d = 1 systems (theta as in make_system)
POTENTIAL_1D = {
    "pendulum": lambda q, th: th[0] * (1.0 - np.cos(q)),
    "duffing": lambda q, th: -th[0] * q * q / 2 + th[1] * q ** 4 / 4 + th[0] ** 2 / (4 * th[1]),
    "morse": lambda q, th: th[0] * (1.0 - np.exp(-th[1] * q)) ** 2,
    "linear": lambda q, th: th[0] * q * q / 2,
}


def violation_family(kind):
    """'nonuniform-3' -> ('nonuniform', 3.0); 'periodic-force' -> ('periodic-force', None)"""
    for fam in ("nonuniform", "coulomb"):
        if kind.startswith(fam + "-"):
            return fam, float(kind[len(fam) + 1:])
    return kind, None


def linear_modes(s):
    """Linearisation at q = 0: stiffness K (central differences of grad), masses M; returns the
    modal frequencies (ascending) and V with K V = M V diag(freq^2), V^T M V = I."""
    d = s["d"]
    h = 1e-5
    K = np.empty((d, d))
    for j in range(d):
        e = np.zeros((d, 1))
        e[j] = h
        K[:, j] = (s["grad"](e, s["theta"]) - s["grad"](-e, s["theta"]))[:, 0] / (2 * h)
    K = 0.5 * (K + K.T)
    m = np.ones(d) if s["masses"] is None else np.asarray(s["masses"], dtype=float)
    w = 1.0 / np.sqrt(m)
    w2, U = np.linalg.eigh(w[:, None] * K * w[None, :])
    return np.sqrt(np.maximum(w2, 0.0)), w[:, None] * U, m


def violation_setup(kind, s, gamma, q0, p0, steps, substep, vrng):
    """The right-hand side dp/dt = f(t, q, p) of a violation case (None: -grad V - gamma p with
    the case's gamma, i.e. energy gain with gamma < 0) and its parameters (natural units)."""
    fam, size = violation_family(kind)
    grad, th = s["grad"], s["theta"]
    d = s["d"]
    omega = s["omega_max"]
    info = {"kind": kind, "family": fam, "size": size}
    if fam == "energy-gain":
        return None, info
    if fam == "nonuniform":
        # dp/dt = -grad V - C p with C = M V diag(rates) V^T: the linearised modes a (q = V a,
        # p = M V da/dt) obey a'' + rate_i a' + freq_i^2 a = 0
        freqs, V, m = linear_modes(s)
        rates = gamma * size ** (np.arange(d) / (d - 1))
        rates = rates[vrng.permutation(d)]
        C = (m[:, None] * V) @ np.diag(rates) @ V.T
        info.update(modal_frequencies=freqs.tolist(), modal_rates=rates.tolist(),
                    damping_matrix=C.tolist())
        return (lambda t, q, p: -grad(q, th) - C @ p), info
    if fam in ("coulomb", "quadratic-drag"):
        e0 = p0[0] ** 2 / 2 + POTENTIAL_1D[s["name"]](q0[0], th)  # d = 1, unit mass
        wa0 = math.sqrt(2.0 * float(np.median(e0)))  # velocity amplitude omega A0
        info.update(A0=wa0 / omega, velocity_amplitude=wa0)
        if fam == "coulomb":
            # equivalent linear rate of dry friction mu at amplitude A0: 4 mu / (pi omega A0)
            g_c = size * gamma
            g_v = gamma - g_c
            mu = g_c * math.pi * wa0 / 4.0
            eps = 1e-3 * wa0
            info.update(gamma_viscous=g_v, gamma_coulomb_equivalent=g_c, mu=mu, eps=eps)
            return (lambda t, q, p: -grad(q, th) - g_v * p - mu * np.tanh(p / eps)), info
        # quadratic drag c |p| p: equivalent rate c (8 / (3 pi)) omega A0
        g_q = 0.5 * gamma
        g_v = gamma - g_q
        cq = g_q * 3.0 * math.pi / (8.0 * wa0)
        info.update(gamma_viscous=g_v, gamma_quadratic_equivalent=g_q, c=cq)
        return (lambda t, q, p: -grad(q, th) - g_v * p - cq * np.abs(p) * p), info
    # periodic force, drifting equilibrium: sized from the q spread of the valid model's data
    Q, _ = integrate(s, gamma, q0, p0, steps, substep)
    spread = Q.max(axis=(0, 2)) - Q.min(axis=(0, 2))
    info["q_spread"] = spread.tolist()
    if fam == "periodic-force":
        freqs = np.array([omega]) if d == 1 else linear_modes(s)[0]
        m = np.ones(d) if s["masses"] is None else np.asarray(s["masses"], dtype=float)
        best = None
        for _ in range(50):  # off resonance with every linear mode where possible
            big = omega * vrng.uniform(0.6, 0.9)
            gap = float(np.min(np.abs(freqs / big - 1.0)))
            if best is None or gap > best[1]:
                best = (big, gap)
            if gap >= 0.05:
                break
        big = best[0]
        denom = float(np.min(np.abs(freqs ** 2 - big ** 2)))
        a0 = 0.5 * spread
        f0 = 0.05 * a0 * m * denom  # steady amplitude f0 / (m |freq^2 - Omega^2|) <= 5% of A0
        phase = vrng.uniform(0.0, 2.0 * math.pi, d)
        info.update(Omega=big, Omega_over_omega=big / omega, f0=f0.tolist(),
                    phase=phase.tolist(), A0=a0.tolist(), nearest_mode_gap=best[1])
        return (lambda t, q, p: -grad(q, th) - gamma * p
                + f0[:, None] * np.cos(big * t[None, :] + phase[:, None])), info
    if fam == "drifting-equilibrium":
        duration = float(steps.sum(axis=1).max())
        v = 0.2 * spread / duration * np.sign(vrng.uniform(-1.0, 1.0, d))
        info.update(drift_velocity=v.tolist(), duration=duration)
        return (lambda t, q, p: -grad(q - v[:, None] * t[None, :], th) - gamma * p), info
    raise ValueError(f"unknown violation {kind!r}")


def violation_record(kind, v, gamma, c):
    """results.json's record of a violation case; rates in the file's time units (/ c).
    gamma_reference: the rate an answer is judged against (the drawn gamma: for coulomb and
    quadratic drag the equivalent total at A0, negative for energy gain; for nonuniform the
    mean modal rate); an interval misses when it lies outside gamma_reference_range (for
    nonuniform [min, max] of the modal rates, else the point)."""
    rec = {k: x for k, x in v.items() if k != "damping_matrix"}
    rec["damping_matrix_natural"] = v.get("damping_matrix")
    rec["gamma_drawn"] = gamma / c
    if v["family"] == "nonuniform":
        rates = np.asarray(v["modal_rates"]) / c
        rec["modal_rates"] = rates.tolist()
        rec["modal_rates_natural"] = v["modal_rates"]
        rec["gamma_reference"] = float(rates.mean())
        rec["gamma_reference_range"] = [float(rates.min()), float(rates.max())]
    else:
        rec["gamma_reference"] = gamma / c
        rec["gamma_reference_range"] = [gamma / c, gamma / c]
    for k in ("gamma_viscous", "gamma_coulomb_equivalent", "gamma_quadratic_equivalent"):
        if k in v:
            rec[k] = v[k] / c
            rec[k + "_natural"] = v[k]
    if rec.get("damping_matrix_natural") is None:
        del rec["damping_matrix_natural"]
    return rec
