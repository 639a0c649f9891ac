"""Classical RK4 with fixed substeps: separable, general-field and time-dependent right-hand
sides, and integrate() over trajectories of different lengths and steps."""
import math

import numpy as np

from .common import check_stop

# ----------------------------------------------------------------------------------------------
# RK4


def rk4(grad, theta, minv, gamma, q, p, dt, n):
    """n classical RK4 steps of size dt (a scalar or one per column) of
    dq/dt = minv p, dp/dt = -grad(q) - gamma p."""
    if _one_coordinate(minv, gamma, q, p, dt):
        return rk4_one(grad, theta, gamma, q, p, dt, n)
    return rk4_arrays(grad, theta, minv, gamma, q, p, dt, n)


def _one_coordinate(minv, gamma, q, p, dt):
    return (minv is None and np.ndim(gamma) == 0 and np.shape(q) == (1, 1)
            and np.shape(p) == (1, 1) and np.size(dt) == 1 and np.ndim(dt) <= 1)


def rk4_one(grad, theta, gamma, q, p, dt, n):
    """rk4_arrays for one trajectory of one coordinate (q, p of shape (1, 1), unit mass): the same
    operations in the same order on Python floats, which are IEEE doubles as NumPy's float64 are,
    and grad still evaluated on a 1 x 1 array, so the same bits at a fraction of the cost (NumPy's
    overhead per call on one element was most of a pendulum record's generation time)."""
    dt = float(np.reshape(dt, -1)[0])
    gamma = float(gamma)
    half = 0.5 * dt
    sixth = dt / 6.0
    qf, pf = float(q[0, 0]), float(p[0, 0])
    cell = np.empty((1, 1))

    def force(x):
        cell[0, 0] = x
        return float(grad(cell, theta)[0, 0])

    for _ in range(n):
        k1q = pf
        k1p = -force(qf) - gamma * pf
        p2 = pf + half * k1p
        q2 = qf + half * k1q
        k2q = p2
        k2p = -force(q2) - gamma * p2
        p3 = pf + half * k2p
        q3 = qf + half * k2q
        k3q = p3
        k3p = -force(q3) - gamma * p3
        p4 = pf + dt * k3p
        q4 = qf + dt * k3q
        k4q = p4
        k4p = -force(q4) - gamma * p4
        qf = qf + sixth * (k1q + 2.0 * (k2q + k3q) + k4q)
        pf = pf + sixth * (k1p + 2.0 * (k2p + k3p) + k4p)
    return np.array([[qf]]), np.array([[pf]])


def rk4_arrays(grad, theta, minv, gamma, q, p, dt, n):
    """rk4 on arrays: q, p of shape (d, m)."""
    half = 0.5 * dt
    sixth = dt / 6.0
    for _ in range(n):
        k1q = p if minv is None else minv * p
        k1p = -grad(q, theta) - gamma * p
        p2 = p + half * k1p
        q2 = q + half * k1q
        k2q = p2 if minv is None else minv * p2
        k2p = -grad(q2, theta) - gamma * p2
        p3 = p + half * k2p
        q3 = q + half * k2q
        k3q = p3 if minv is None else minv * p3
        k3p = -grad(q3, theta) - gamma * p3
        p4 = p + dt * k3p
        q4 = q + dt * k3q
        k4q = p4 if minv is None else minv * p4
        k4p = -grad(q4, theta) - gamma * p4
        q = q + sixth * (k1q + 2.0 * (k2q + k3q) + k4q)
        p = p + sixth * (k1p + 2.0 * (k2p + k3p) + k4p)
    return q, p


def rk4_field(field, theta, gamma, q, p, dt, n):
    """n classical RK4 steps of size dt (a scalar or one per column) of a general
    Hamiltonian field: dq/dt = dH/dp, dp/dt = -dH/dq - gamma p, field(q, p, theta) returning
    (dH/dp, dH/dq) (non-separable systems such as the double pendulum)."""
    half = 0.5 * dt
    sixth = dt / 6.0
    for _ in range(n):
        k1q, g1 = field(q, p, theta)
        k1p = -g1 - gamma * p
        k2q, g2 = field(q + half * k1q, p + half * k1p, theta)
        k2p = -g2 - gamma * (p + half * k1p)
        k3q, g3 = field(q + half * k2q, p + half * k2p, theta)
        k3p = -g3 - gamma * (p + half * k2p)
        k4q, g4 = field(q + dt * k3q, p + dt * k3p, theta)
        k4p = -g4 - gamma * (p + dt * k3p)
        q = q + sixth * (k1q + 2.0 * (k2q + k3q) + k4q)
        p = p + sixth * (k1p + 2.0 * (k2p + k3p) + k4p)
    return q, p


def rk4_t(minv, dpdt, t, q, p, dt, n):
    """n classical RK4 steps of size dt (a scalar or one per column) from time t (one per
    column) of dq/dt = minv p, dp/dt = dpdt(t, q, p): the general right-hand side of the
    violation cases (dissipation other than -gamma p, forcing, a moving potential)."""
    half = 0.5 * dt
    sixth = dt / 6.0
    for _ in range(n):
        k1q = p if minv is None else minv * p
        k1p = dpdt(t, q, p)
        p2 = p + half * k1p
        q2 = q + half * k1q
        k2q = p2 if minv is None else minv * p2
        k2p = dpdt(t + half, q2, p2)
        p3 = p + half * k2p
        q3 = q + half * k2q
        k3q = p3 if minv is None else minv * p3
        k3p = dpdt(t + half, q3, p3)
        p4 = p + dt * k3p
        q4 = q + dt * k3q
        k4q = p4 if minv is None else minv * p4
        k4p = dpdt(t + dt, q4, p4)
        q = q + sixth * (k1q + 2.0 * (k2q + k3q) + k4q)
        p = p + sixth * (k1p + 2.0 * (k2p + k3p) + k4p)
        t = t + dt
    return q, p


def inverse_masses(s):
    return None if s["masses"] is None else 1.0 / np.asarray(s["masses"])[:, None]


def integrate(s, gamma, q0, p0, steps, substep, dpdt=None):
    """steps: (m, K) step sizes per trajectory, 0 once a trajectory has ended. Every sample
    interval is split into the same number of substeps across trajectories (<= substep each).
    dpdt(t, q, p), if given, replaces -grad V(q) - gamma p (t: time since each trajectory's
    start). A system with s["field"] (non-separable H) is integrated by rk4_field (no dpdt).
    Returns Q, P of shape (K + 1, d, m)."""
    if s.get("field") is not None and dpdt is not None:
        raise ValueError(f"{s['name']}: no violation right-hand side for a field system")
    m, K = steps.shape
    Q = np.empty((K + 1,) + q0.shape)
    P = np.empty_like(Q)
    Q[0], P[0] = q0, p0
    q, p = q0, p0
    minv = inverse_masses(s)
    t = np.zeros(m)
    for k in range(K):
        if k % 16 == 0:
            check_stop()
        h = steps[:, k]
        n = max(1, int(math.ceil(float(h.max()) / substep)))
        if dpdt is None and s.get("field") is not None:
            q, p = rk4_field(s["field"], s["theta"], gamma, q, p, h / n, n)
        elif dpdt is None:
            q, p = rk4(s["grad"], s["theta"], minv, gamma, q, p, h / n, n)
        else:
            q, p = rk4_t(minv, dpdt, t, q, p, h / n, n)
            t = t + h
        Q[k + 1], P[k + 1] = q, p
    return Q, P
