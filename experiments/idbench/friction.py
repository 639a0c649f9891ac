"""The friction plan's systems and records (--friction-plan): free decays with viscous damping
plus dry (Coulomb) friction or quadratic drag, recorded exactly, as docs/identification.md's
"Dry friction and drag" describes them:

    q'' = -omega^2 q - gamma q' - mu sign(q')        (Coulomb: a deceleration mu)
    q'' = -omega^2 q - gamma q' - c q' |q'|          (drag)
    q'' = -omega^2 sin q - gamma q' - mu sign(q')    (a pendulum with dry friction)

A body that comes to rest where the restoring force is at most mu stays there (static friction
equal to kinetic).

Strata (the plan takes them in turn; a case's draws come from its own seed):

    viscous             the oscillator with viscous damping alone: gamma = U(0.03, 0.15),
                        omega = U(1.5, 3); four decays of 40 s from amplitudes 0.8-2 at 30
                        samples a period; q and p with noise 0.1-1% of their spread
    coulomb             the same plus Coulomb friction, a share U(0.1, 0.9) of the dissipation
                        over the first decay (the energy-equivalent rate 4 mu / (pi omega A)
                        against gamma / 2 at A = 1.4)
    drag                the same plus quadratic drag c = U(0.05, 0.3)
    coulomb-positions   the coulomb stratum's records, positions alone
    encoder-pendulum    a pendulum read by a 1024-count encoder at 100 Hz: omega = U(3.5, 4.5)
                        rad/s, gamma = U(0.02, 0.04), dry friction as strong as the viscous
                        damping over the first decay (share U(0.35, 0.65)), two decays of 40 s
                        from 0.6-1.2 rad; positions only, in counts with an offset of
                        1,000-30,000 counts, no other noise
    coulomb-2dof        two masses in a chain, each with its own dry friction, with velocities
    coulomb-2dof-positions   the same, positions alone (idbench/friction_chain.py)

Records are exact: the oscillators in closed form between reversals (Coulomb) or RK4 at 400
substeps a sample (drag); the pendulum by RK4 at 40 substeps a sample, each reversal located by
bisection and the stick test applied there. The same simulators, with fewer substeps, are the
oracle's model (peers/friction_oracle.py). (--quick: 20 s decays.)
"""
import math

import numpy as np

from .friction_chain import CHAIN_STRATA, generate_chain

FRICTION_STRATA = ["viscous", "coulomb", "drag", "coulomb-positions", "encoder-pendulum"] + CHAIN_STRATA
ENCODER_COUNTS = 1024


# ----------------------------------------------------------------------------------------------
# Exact flows


def coulomb_advance(omega, gamma, mu, q, v, T):
    """(q, v) after time T of q'' = -omega^2 q - gamma q' - mu sign(q'), exactly (underdamped):
    the damped oscillator about the shifted centre between reversals, sticking for good at a
    reversal where |omega^2 q| <= mu."""
    w2 = omega * omega
    wd = math.sqrt(w2 - 0.25 * gamma * gamma)
    left = T
    while left > 0.0:
        if v == 0.0 and w2 * abs(q) <= mu:
            return q, 0.0
        s = (1.0 if v > 0 else -1.0) if v != 0.0 else (-1.0 if q > 0 else 1.0)
        c = -mu * s / w2
        a = q - c
        b = (v + 0.5 * gamma * a) / wd
        cc, dd = v, a * wd + 0.5 * gamma * b
        phase = math.fmod(math.atan2(cc, dd), math.pi)
        if phase < 0.0:
            phase += math.pi
        if phase <= 1e-15:
            phase += math.pi
        t_zero = phase / wd
        t = min(left, t_zero)
        e, cs, sn = math.exp(-0.5 * gamma * t), math.cos(wd * t), math.sin(wd * t)
        q = c + e * (a * cs + b * sn)
        v = e * (cc * cs - dd * sn) if t < t_zero else 0.0
        left -= t
    return q, v


def drag_advance(omega, gamma, c, q, v, T, sub=400):
    """(q, v) after time T of q'' = -omega^2 q - gamma q' - c q'|q'|, by RK4 at `sub` steps."""
    dt = T / sub
    acc = lambda qq, vv: -omega * omega * qq - gamma * vv - c * vv * abs(vv)
    for _ in range(sub):
        a1, b1 = v, acc(q, v)
        a2 = v + 0.5 * dt * b1
        b2 = acc(q + 0.5 * dt * a1, a2)
        a3 = v + 0.5 * dt * b2
        b3 = acc(q + 0.5 * dt * a2, a3)
        a4 = v + dt * b3
        b4 = acc(q + dt * a3, a4)
        q += dt / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
        v += dt / 6 * (b1 + 2 * b2 + 2 * b3 + b4)
    return q, v


def _pendulum_rk4(w2, gamma, mu, s, q, v, dt):
    """one RK4 step of the pendulum with the friction's sign s held"""
    acc = lambda qq, vv: -w2 * math.sin(qq) - gamma * vv - mu * s
    a1, b1 = v, acc(q, v)
    a2 = v + 0.5 * dt * b1
    b2 = acc(q + 0.5 * dt * a1, a2)
    a3 = v + 0.5 * dt * b2
    b3 = acc(q + 0.5 * dt * a2, a3)
    a4 = v + dt * b3
    b4 = acc(q + dt * a3, a4)
    return q + dt / 6 * (a1 + 2 * a2 + 2 * a3 + a4), v + dt / 6 * (b1 + 2 * b2 + 2 * b3 + b4)


def pendulum_friction_advance(omega, gamma, mu, q, v, T, sub=40, bisections=30):
    """(q, v) after time T of q'' = -omega^2 sin q - gamma q' - mu sign(q') by RK4 at `sub`
    steps. A step in which q' changes sign is cut at the reversal (bisection on the step's
    length); there the body sticks for good when |omega^2 sin q| <= mu, else it goes on with
    the friction's sign reversed."""
    w2 = omega * omega
    dt = T / sub
    for _ in range(sub):
        left = dt
        while left > 0.0:
            if v == 0.0:
                if w2 * abs(math.sin(q)) <= mu:
                    return q, 0.0
                s = -1.0 if math.sin(q) > 0 else 1.0
            else:
                s = 1.0 if v > 0 else -1.0
            qn, vn = _pendulum_rk4(w2, gamma, mu, s, q, v, left)
            if vn * s > 0.0:
                q, v, left = qn, vn, 0.0
                continue
            lo, hi = 0.0, left  # the reversal lies in (lo, hi]
            for _ in range(bisections):
                mid = 0.5 * (lo + hi)
                _, vm = _pendulum_rk4(w2, gamma, mu, s, q, v, mid)
                if vm * s > 0.0:
                    lo = mid
                else:
                    hi = mid
            q, _ = _pendulum_rk4(w2, gamma, mu, s, q, v, hi)
            v = 0.0
            left -= hi
    return q, v


def simulate(kind, omega, gamma, rate, q0, v0, h, points, substeps=None):
    """(points, 2) states [q, q'] from (q0, v0) at step h. kind: viscous, coulomb, drag
    (oscillators) or pendulum-coulomb; substeps: the RK4 substeps a sample (None: the
    records' own, 400 for drag and 40 for the pendulum; the Coulomb oscillator is exact)."""
    z = np.empty((points, 2))
    q, v = float(q0), float(v0)
    for k in range(points):
        z[k] = (q, v)
        if k + 1 == points:
            break
        if kind == "drag":
            q, v = drag_advance(omega, gamma, rate, q, v, h, sub=substeps or 400)
        elif kind == "pendulum-coulomb":
            q, v = pendulum_friction_advance(omega, gamma, rate, q, v, h, sub=substeps or 40)
        else:
            q, v = coulomb_advance(omega, gamma, rate if kind == "coulomb" else 0.0, q, v, h)
    return z


# ----------------------------------------------------------------------------------------------
# The plan and its records


def plan_friction(n, seed, strata):
    cases = []
    for i in range(n):
        st = strata[i % len(strata)]
        cases.append({"index": i, "id": f"f{i:03d}-{st}", "stratum": st,
                      "within": i // len(strata), "seed": [seed, 400000 + i],
                      "strata": {"friction": st}})
    return cases


def _oscillator_truth(st, rng):
    omega = float(rng.uniform(1.5, 3.0))
    gamma = float(rng.uniform(0.03, 0.15))
    kind = {"viscous": "viscous", "drag": "drag"}.get(st, "coulomb")
    rate, share = 0.0, None
    if kind == "coulomb":
        share = float(rng.uniform(0.1, 0.9))
        # 4 mu / (pi omega A) = share / (1 - share) * gamma / 2 at A = 1.4
        rate = share / (1 - share) * 0.5 * gamma * math.pi * omega * 1.4 / 4.0
    elif kind == "drag":
        rate = float(rng.uniform(0.05, 0.3))
    return {"kind": kind, "omega": omega, "gamma": gamma, "rate": rate, "share": share}


def _pendulum_truth(rng):
    omega = float(rng.uniform(3.5, 4.5))
    gamma = float(rng.uniform(0.02, 0.04))
    share = float(rng.uniform(0.35, 0.65))
    rate = share / (1 - share) * 0.5 * gamma * math.pi * omega * 0.9 / 4.0
    return {"kind": "pendulum-coulomb", "omega": omega, "gamma": gamma, "rate": rate,
            "share": share}


def generate_friction(case, quick=False):
    """The case's record: {"t": (n,), "traj": (n,), "q": (n,), "p": (n,) or None, "columns"},
    and its truth (kind, omega, gamma, rate in the record's units, the unit's scale and
    offset, noise)."""
    rng = np.random.default_rng(case["seed"])
    st = case["stratum"]
    if st in CHAIN_STRATA:
        return generate_chain(case, rng, quick)
    span = 20.0 if quick else 40.0
    if st == "encoder-pendulum":
        truth = _pendulum_truth(rng)
        h = 0.01
        starts = [(float(rng.uniform(0.6, 1.2)) * float(rng.choice([-1, 1])), 0.0)
                  for _ in range(2)]
    else:
        truth = _oscillator_truth(st, rng)
        h = 2 * math.pi / truth["omega"] / 30
        starts = [(float(rng.uniform(0.8, 2.0)) * float(rng.choice([-1, 1])),
                   float(rng.uniform(-1, 1))) for _ in range(4)]
    points = int(round(span / h))
    z = [simulate(truth["kind"], truth["omega"], truth["gamma"], truth["rate"], q0, v0, h, points)
         for q0, v0 in starts]
    t = np.arange(points) * h
    if st == "encoder-pendulum":
        scale = ENCODER_COUNTS / (2 * math.pi)
        offset = float(rng.uniform(1000.0, 30000.0))
        q = [np.round(zz[:, 0] * scale + offset) for zz in z]
        p, sigma = None, 0.0
    else:
        scale, offset = 1.0, 0.0
        sigma = float(math.exp(rng.uniform(math.log(1e-3), math.log(1e-2))))
        noisy = [zz + sigma * zz.std(axis=0)[None, :] * rng.standard_normal(zz.shape) for zz in z]
        q = [zz[:, 0] for zz in noisy]
        p = None if st == "coulomb-positions" else [zz[:, 1] for zz in noisy]
    truth.update(h=h, points=points, starts=starts, sigma=sigma, scale=scale, offset=offset,
                 positions_only=p is None,
                 # the rate in the record's units: mu in q units per s^2, c per q unit
                 rate_in_units=(truth["rate"] * scale if truth["kind"] != "drag"
                                else truth["rate"] / scale))
    rec = {"t": np.concatenate([t] * len(z)),
           "traj": np.concatenate([np.full(points, j) for j in range(len(z))]),
           "q": np.concatenate(q), "p": None if p is None else np.concatenate(p)}
    return rec, truth


def write_friction_csv(path, rec):
    q = rec["q"].reshape(rec["t"].size, -1)
    p = None if rec["p"] is None else rec["p"].reshape(rec["t"].size, -1)
    d = q.shape[1]
    cols = (["traj", "t"] + [f"q{i + 1}" for i in range(d)]
            + ([] if p is None else [f"p{i + 1}" for i in range(d)]))
    with open(path, "w") as f:
        f.write(",".join(cols) + "\n")
        for k in range(rec["t"].size):
            row = [f"{int(rec['traj'][k])}", f"{rec['t'][k]:.17g}"]
            row += [f"{x:.17g}" for x in q[k]]
            if p is not None:
                row += [f"{x:.17g}" for x in p[k]]
            f.write(",".join(row) + "\n")
