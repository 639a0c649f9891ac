"""The benchmark's systems (make_system) and the lists of their names."""
import math

import numpy as np

# ----------------------------------------------------------------------------------------------
# Systems. Each is a dict: name, d, theta (true potential parameters), theta_names, masses,
# grad(q, theta) with q of shape (d, m), omega_max, init(rng, m) -> (q0, p0) each (d, m).


def _chain_grad(bond_force):
    def grad(q, th):
        zero = np.zeros((1, q.shape[1]))
        x = np.diff(np.concatenate([zero, q, zero]), axis=0)  # d + 1 bonds, fixed ends
        f = bond_force(x, th)
        return f[:-1] - f[1:]
    return grad


def _chain_omega(stiffness, d):
    return 2.0 * math.sqrt(stiffness) * math.sin(d * math.pi / (2.0 * (d + 1)))


def _sample_by_energy(rng, m, potential, e_lo, e_hi, q_lo, q_hi):
    """1-d: an energy uniform in [e_lo, e_hi], q uniform where V(q) < E, p of either sign."""
    q0 = np.empty(m)
    p0 = np.empty(m)
    for j in range(m):
        e = rng.uniform(e_lo, e_hi)
        while True:
            q = rng.uniform(q_lo, q_hi)
            v = potential(q)
            if v < e:
                break
        q0[j] = q
        p0[j] = math.copysign(math.sqrt(2.0 * (e - v)), rng.uniform(-1, 1))
    return q0[None, :], p0[None, :]


def _states_in_energy_band(rng, m, box, energy, e_lo, e_hi):
    """m states of d = 2, q and p uniform in [-box, box]^2 (q drawn first), each redrawn until
    e_lo < energy(q, p) < e_hi; returns q0, p0 of shape (2, m)."""
    q0 = np.empty((2, m))
    p0 = np.empty((2, m))
    for j in range(m):
        while True:
            q = rng.uniform(-box, box, 2)
            p = rng.uniform(-box, box, 2)
            if e_lo < energy(q, p) < e_hi:
                break
        q0[:, j], p0[:, j] = q, p
    return q0, p0


def _double_pendulum_energy(q, p, th):
    """H of the planar double pendulum, unit lengths and masses, canonical momenta."""
    dl = q[0] - q[1]
    sn = np.sin(dl)
    kin = (p[0] * p[0] + 2.0 * p[1] * p[1] - 2.0 * p[0] * p[1] * np.cos(dl)) \
        / (2.0 * (1.0 + sn * sn))
    return kin - 2.0 * th[0] * np.cos(q[0]) - th[0] * np.cos(q[1])


def _double_pendulum_field(q, p, th):
    """(dH/dp, dH/dq) of _double_pendulum_energy; q, p of shape (2, m)."""
    dl = q[0] - q[1]
    c, sn = np.cos(dl), np.sin(dl)
    den = 1.0 + sn * sn
    p1, p2 = p[0], p[1]
    dq = np.stack([(p1 - p2 * c) / den, (2.0 * p2 - p1 * c) / den])
    num_ = p1 * p1 + 2.0 * p2 * p2 - 2.0 * p1 * p2 * c
    a = sn * (p1 * p2 / den - num_ * c / (den * den))  # d(kinetic)/d(q1 - q2)
    return dq, np.stack([a + 2.0 * th[0] * np.sin(q[0]), -a + th[0] * np.sin(q[1])])


def make_system(name, rng, quick):
    s = {"name": name, "masses": None, "field": None}
    if name == "pendulum":
        s.update(d=1, theta=[1.0], theta_names=["k"])
        s["grad"] = lambda q, th: th[0] * np.sin(q)
        s["omega_max"] = 1.0

        def init(rng, m):
            amp = rng.uniform(0.2, 2.5, m)
            q0 = amp * rng.uniform(-1.0, 1.0, m)
            p0 = np.sqrt(2.0 * (np.cos(q0) - np.cos(amp))) * np.sign(rng.uniform(-1, 1, m))
            return q0[None, :], p0[None, :]
    elif name == "duffing":
        s.update(d=1, theta=[1.0, 1.0], theta_names=["a", "b"])
        s["grad"] = lambda q, th: -th[0] * q + th[1] * q ** 3
        s["omega_max"] = math.sqrt(2.0)  # about either well

        def init(rng, m):
            above = rng.uniform() < 0.5  # one energy regime per case
            lo, hi = (0.05, 0.8) if above else (-0.23, -0.03)
            return _sample_by_energy(rng, m, lambda q: -q * q / 2 + q ** 4 / 4, lo, hi, -2.2, 2.2)
    elif name == "morse":
        s.update(d=1, theta=[1.0, 1.0], theta_names=["D", "a"])

        def grad(q, th):
            e = np.exp(-th[1] * q)
            return 2.0 * th[0] * th[1] * (1.0 - e) * e
        s["grad"] = grad
        s["omega_max"] = math.sqrt(2.0)  # a sqrt(2 D)

        def init(rng, m):
            return _sample_by_energy(rng, m, lambda q: (1 - math.exp(-q)) ** 2, 0.05, 0.6,
                                     -1.0, 3.0)
    elif name == "linear":
        s.update(d=1, theta=[25.0], theta_names=["k"])
        s["grad"] = lambda q, th: th[0] * q
        s["omega_max"] = 5.0

        def init(rng, m):
            amp = rng.uniform(0.5, 2.0, m)
            ph = rng.uniform(0, 2 * math.pi, m)
            return (amp * np.cos(ph))[None, :], (-5.0 * amp * np.sin(ph))[None, :]
    elif name == "toda":
        d = int(rng.integers(3, 5 if quick else 9))
        s.update(d=d, theta=[1.0, 1.0], theta_names=["A", "b"])
        s["grad"] = _chain_grad(lambda x, th: -th[0] * th[1] * np.exp(-th[1] * x))
        s["omega_max"] = _chain_omega(1.0, d)

        def init(rng, m):
            a = rng.uniform(0.15, 0.5, m)
            return a * rng.standard_normal((d, m)), a * rng.standard_normal((d, m))
    elif name in ("fpu-alpha", "fpu-beta"):
        d = 4 if quick else int(rng.choice([4, 8, 16]))
        if name == "fpu-alpha":
            s.update(d=d, theta=[1.0, 0.25], theta_names=["k", "alpha"])
            s["grad"] = _chain_grad(lambda x, th: th[0] * x + th[1] * x * x)
            lo, hi = 0.05, 0.3
        else:
            s.update(d=d, theta=[1.0, 1.0], theta_names=["k", "beta"])
            s["grad"] = _chain_grad(lambda x, th: th[0] * x + th[1] * x ** 3)
            lo, hi = 0.1, 0.5
        s["omega_max"] = _chain_omega(1.0, d)

        def init(rng, m):
            a = rng.uniform(lo, hi, m)
            return a * rng.standard_normal((d, m)), a * rng.standard_normal((d, m))
    elif name == "henon-heiles":
        s.update(d=2, theta=[1.0, 1.0], theta_names=["w", "lam"])

        def grad(q, th):
            q1, q2 = q[0], q[1]
            return np.stack([th[0] * q1 + 2.0 * th[1] * q1 * q2,
                             th[0] * q2 + th[1] * (q1 * q1 - q2 * q2)])
        s["grad"] = grad
        s["omega_max"] = 1.0

        def init(rng, m):
            return _states_in_energy_band(
                rng, m, 0.35, lambda q, p: 0.5 * (p @ p + q @ q) + q[0] ** 2 * q[1] - q[1] ** 3 / 3,
                0.01, 0.12)
    elif name == "coupled-pendulums":
        masses = np.array([1.0, 2.5])
        s.update(d=2, theta=[1.0, 0.4], theta_names=["g", "kc"], masses=masses.tolist())

        def grad(q, th):
            c = th[1] * (q[0] - q[1])
            return np.stack([masses[0] * th[0] * np.sin(q[0]) + c,
                             masses[1] * th[0] * np.sin(q[1]) - c])
        s["grad"] = grad
        k = np.diag(masses * 1.0) + 0.4 * np.array([[1.0, -1.0], [-1.0, 1.0]])
        s["omega_max"] = float(math.sqrt(max(np.linalg.eigvals(k / masses[:, None]).real)))

        def init(rng, m):
            return rng.uniform(-1.0, 1.0, (2, m)), masses[:, None] * rng.uniform(-0.5, 0.5, (2, m))
    elif name == "softened-central":
        s.update(d=2, theta=[1.0, 0.5], theta_names=["k", "eps"])

        def grad(q, th):
            r2 = q[0] * q[0] + q[1] * q[1] + th[1] * th[1]
            return th[0] * q / (r2 * np.sqrt(r2))
        s["grad"] = grad
        s["omega_max"] = math.sqrt(1.0 / 0.5 ** 3)

        def init(rng, m):
            radius = rng.uniform(0.4, 1.5, m)
            ph = rng.uniform(0, 2 * math.pi, m)
            v = np.sqrt(radius * radius / (radius * radius + 0.25) ** 1.5)  # circular speed
            v = v * rng.uniform(0.8, 1.15, m)
            vr = v * rng.uniform(-0.2, 0.2, m)
            c, sn = np.cos(ph), np.sin(ph)
            return (np.stack([radius * c, radius * sn]),
                    np.stack([-v * sn + vr * c, v * c + vr * sn]))
    elif name == "double-pendulum":
        # Non-separable H (kinetic energy depends on q1 - q2): the system supplies the full
        # field (dq/dt = dH/dp, dH/dq) instead of masses and grad V.
        s.update(d=2, theta=[1.0], theta_names=["g"])
        s["grad"] = None
        s["field"] = _double_pendulum_field
        s["omega_max"] = math.sqrt(2.0 + math.sqrt(2.0))  # sqrt(g (2 + sqrt 2)) at q = 0

        def init(rng, m):
            # angles and momenta uniform in [-0.8, 0.8], kept when the energy above the
            # minimum (-3 g) is in [0.05, 0.6]: |q1| <= 0.80, |q2| <= 1.16 rad for all times
            return _states_in_energy_band(
                rng, m, 0.8, lambda q, p: float(_double_pendulum_energy(q, p, [1.0])) + 3.0,
                0.05, 0.6)
    else:
        raise ValueError(f"unknown system {name!r}")
    s["init"] = init
    return s


# The systems of the default plan (no --systems). The plan cycles through its system list, so
# a system added to this list would move every case of every seed: new systems go to
# EXTRA_SYSTEMS instead and are planned only when --systems names them (or "all").
DEFAULT_SYSTEMS = ["pendulum", "duffing", "morse", "linear", "toda", "fpu-alpha", "fpu-beta",
                   "henon-heiles", "coupled-pendulums", "softened-central"]
EXTRA_SYSTEMS = ["double-pendulum"]
SYSTEM_NAMES = DEFAULT_SYSTEMS + EXTRA_SYSTEMS
