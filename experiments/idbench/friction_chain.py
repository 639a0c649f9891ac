"""The friction plan's two-degree-of-freedom records (strata coulomb-2dof and
coulomb-2dof-positions): a chain of two unit masses between walls, viscous damping on each and
dry friction of its own on each,

    q'' = -K q - gamma q' - mu * sign(q')        (mu a vector: each mass its own deceleration)

K = [[k1 + k2, -k2], [-k2, k2 + k3]], k = U(1.5, 6) each. The friction shares the dissipation
as in the one-dof coulomb stratum, per mass: mu_i = share / (1 - share) * gamma / 2 *
pi * omega_i * 1.4 / 4 with omega_i = sqrt(K_ii) and one share U(0.1, 0.9). Four decays of
40 s from positions U(0.8, 2) of either sign and velocities U(-1, 1), at 30 samples a period of
the faster mode; q (and q' unless positions alone) with noise 0.1-1% of each column's spread.

The record is exact. Between events the motion is linear and affine in the state: each mass
slips with a fixed sign of its friction or sticks (q_i and q_i' held), so a step is the matrix
exponential of that mode's generator. The events are a slipping mass's velocity reaching 0 and
a sticking mass's spring force -(K q)_i exceeding its friction mu_i in size; each is located by
bisection on the exact flow (to ~1e-13 of the step), the step split into 8 pieces so that no
event is stepped over. At an event the mass sticks when |(K q)_i| <= mu_i (static friction equal
to kinetic) and otherwise slips the other way. With K diagonal it is the one-dof closed form
(idbench/friction.py's coulomb_advance) to rounding: tests/experiments/idbench_friction_test.py.

The oracle on these records is the true form given to `csympnet fit`
(peers/chain_oracle.py); no envelope fit runs on them. An independent least squares through the
exact simulator above, with finite differences over 22 unknowns, would take minutes a case.
"""
import math

import numpy as np

CHAIN_STRATA = ["coulomb-2dof", "coulomb-2dof-positions"]


def _generator(k, gamma, mu, mode):
    """the (2d+1)-square generator of (q, q', 1) in a mode: mode[i] = +1 or -1 while mass i
    slips with that sign of q_i', 0 while it sticks"""
    d = k.shape[0]
    a = np.zeros((2 * d + 1, 2 * d + 1))
    for i in range(d):
        if mode[i] == 0:
            continue
        a[i, d + i] = 1.0
        a[d + i, :d] = -k[i]
        a[d + i, d + i] = -gamma
        a[d + i, 2 * d] = -mu[i] * mode[i]
    return a


class CoulombChain:
    """q'' = -K q - gamma q' - mu sign(q'), advanced exactly (module docstring)"""

    def __init__(self, k, gamma, mu):
        self.k = np.asarray(k, dtype=float)
        self.gamma = float(gamma)
        self.mu = np.asarray(mu, dtype=float)
        self.d = self.k.shape[0]
        self._steps = {}

    def _flow(self, mode, t, keep=False):
        from scipy.linalg import expm
        if keep:
            p = self._steps.get((mode, t))
            if p is None:
                p = self._steps[(mode, t)] = expm(_generator(self.k, self.gamma, self.mu, mode) * t)
            return p
        return expm(_generator(self.k, self.gamma, self.mu, mode) * t)

    def _holds(self, mode, z):
        """whether the mode still holds at z: each slipping mass moves its way, each sticking
        mass's spring force is within its friction"""
        d = self.d
        force = -self.k @ z[:d]
        for i in range(d):
            if mode[i] != 0 and z[d + i] * mode[i] <= 0.0:
                return False
            if mode[i] == 0 and abs(force[i]) > self.mu[i]:
                return False
        return True

    def mode_at(self, mode, z):
        """the mode at an event (z changed in place: a mass that stops has q_i' = 0 exactly)"""
        d = self.d
        force = -self.k @ z[:d]
        out = list(mode)
        for i in range(d):
            if out[i] != 0 and z[d + i] * out[i] <= 0.0:
                z[d + i] = 0.0
                out[i] = 0
            if out[i] == 0:
                z[d + i] = 0.0
                out[i] = 0 if abs(force[i]) <= self.mu[i] else (1 if force[i] > 0 else -1)
        return tuple(out)

    def advance(self, z, mode, step, pieces=8, bisections=45):
        """(z, mode) after time `step`"""
        piece = step / pieces
        for _ in range(pieces):
            left, events = piece, 0
            while left > 0.0:
                zn = self._flow(mode, left, keep=left == piece) @ z
                if self._holds(mode, zn):
                    z, left = zn, 0.0
                    continue
                lo, hi = 0.0, left  # the event lies in (lo, hi]
                for _ in range(bisections):
                    mid = 0.5 * (lo + hi)
                    if self._holds(mode, self._flow(mode, mid) @ z):
                        lo = mid
                    else:
                        hi = mid
                z = self._flow(mode, hi) @ z
                mode = self.mode_at(mode, z)
                left -= hi
                events += 1
                if events > 1000:
                    raise RuntimeError("coulomb chain: more than 1000 events in one piece")
        return z, mode


def simulate_chain(k, gamma, mu, q0, v0, h, points):
    """(points, 2d) states [q, q'] from (q0, v0) at step h"""
    chain = CoulombChain(k, gamma, mu)
    d = chain.d
    z = np.concatenate([np.asarray(q0, float), np.asarray(v0, float), [1.0]])
    mode = tuple(int(np.sign(v)) for v in z[d:2 * d])
    mode = chain.mode_at(mode, z) if 0 in mode else mode
    out = np.empty((points, 2 * d))
    for n in range(points):
        out[n] = z[:2 * d]
        if n + 1 < points:
            z, mode = chain.advance(z, mode, h)
    return out


def chain_truth(rng):
    springs = rng.uniform(1.5, 6.0, size=3)
    k = np.array([[springs[0] + springs[1], -springs[1]],
                  [-springs[1], springs[1] + springs[2]]])
    gamma = float(rng.uniform(0.03, 0.15))
    share = float(rng.uniform(0.1, 0.9))
    omega_i = np.sqrt(np.diag(k))
    mu = share / (1 - share) * 0.5 * gamma * math.pi * omega_i * 1.4 / 4.0
    modes = np.sqrt(np.linalg.eigvalsh(k))
    return {"kind": "coulomb", "d": 2, "k": k.tolist(), "omega": [float(w) for w in modes],
            "gamma": gamma, "rate": [float(m) for m in mu], "share": share}


def generate_chain(case, rng, quick=False):
    """the case's record and truth (as idbench.friction.generate_friction's)"""
    truth = chain_truth(rng)
    span = 20.0 if quick else 40.0
    h = 2 * math.pi / max(truth["omega"]) / 30
    starts = [([float(rng.uniform(0.8, 2.0)) * float(rng.choice([-1, 1])) for _ in range(2)],
               [float(rng.uniform(-1, 1)) for _ in range(2)]) for _ in range(4)]
    points = int(round(span / h))
    z = [simulate_chain(np.array(truth["k"]), truth["gamma"], truth["rate"], q0, v0, h, points)
         for q0, v0 in starts]
    sigma = float(math.exp(rng.uniform(math.log(1e-3), math.log(1e-2))))
    noisy = [zz + sigma * zz.std(axis=0)[None, :] * rng.standard_normal(zz.shape) for zz in z]
    positions_only = case["stratum"].endswith("-positions")
    truth.update(h=h, points=points, starts=starts, sigma=sigma, scale=1.0, offset=0.0,
                 positions_only=positions_only, rate_in_units=list(truth["rate"]))
    t = np.arange(points) * h
    rec = {"t": np.concatenate([t] * len(z)),
           "traj": np.concatenate([np.full(points, j) for j in range(len(z))]),
           "q": np.concatenate([zz[:, :2] for zz in noisy]),
           "p": None if positions_only else np.concatenate([zz[:, 2:] for zz in noisy])}
    return rec, truth
