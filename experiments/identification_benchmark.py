#!/usr/bin/python3
"""Identification benchmark: recover the damping rate gamma of damped Hamiltonian systems from
snapshot data with `csympnet fit`, side by side with two peers, over >= 100 generated cases.

Command (from the repository root; needs only /usr/bin/python3 with NumPy):

    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/idbench   # 120 cases
    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/b --fit-args="--epochs 2000"
    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/idq --quick --only-peers
    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/idv --violations  # 60
    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/idl --library \
        --systems all      # + csympnet_library; every system, the double pendulum included

Options: --cases N (default 120, 8 with --quick; with --violations 60, 10 with --quick),
--quick (a few cases of small size), --violations (only violation cases, below), --seed S
(default 1; everything is deterministic given the seed), --only-peers (skip csympnet, and
csympnet_library), --systems a,b,... (a subset of the systems below, in the order given; "all":
every system; default: every system but double-pendulum, see below), --csympnet PATH (default
build/bin/csympnet under the repository root), --fit-args="..." (extra options for every
`csympnet fit`, split like a shell would; write it with "=" so that a value starting with "--"
is not taken for an option of this script), --timeout SECONDS (per fit, default 600),
--jobs N (cases in parallel, default 1), --force (reuse a non-empty --out), --momenta
given|gradient|savgol (the p columns as generated, default, or computed from the noisy q by
numpy.gradient or a Savitzky-Golay derivative, as a user without a momentum sensor would),
--observed (every case also fitted from its positions alone and with centred-difference
momenta, side by side: methods csympnet_positions and csympnet_differenced), --library
(every case also fitted with the Hamiltonian-library core forced: method csympnet_library; off
by default), --skip-peers (csympnet alone: no SINDy-style peer, no oracle; csympnet_library
still runs with --library).

Systems (dq/dt = M^-1 p, dp/dt = -grad V(q) - gamma p, unit masses, unless stated):

    pendulum            d = 1   V = -k cos q                          (libration)
    duffing             d = 1   V = -a q^2/2 + b q^4/4                (below or above the barrier)
    morse               d = 1   V = D (1 - exp(-a q))^2               (bound: E < D)
    linear              d = 1   V = k q^2/2, k = 25 (omega = 5)
    toda                d = 3..8  fixed ends, V = A sum exp(-b (q_{i+1} - q_i))
    fpu-alpha           d = 4, 8, 16  fixed ends, bond energy k x^2/2 + alpha x^3/3 (small)
    fpu-beta            d = 4, 8, 16  fixed ends, bond energy k x^2/2 + beta x^4/4
    henon-heiles        d = 2   V = w (q1^2 + q2^2)/2 + lam (q1^2 q2 - q2^3/3)   (E < 1/6)
    coupled-pendulums   d = 2   masses (1, 2.5), canonical momenta p_i = m_i dq_i/dt,
                                V = -g sum m_i cos q_i + kc (q1 - q2)^2/2
    softened-central    d = 2   V = -k / sqrt(|q|^2 + eps^2)          (bound orbits, E < 0)
    double-pendulum     d = 2   planar, unit lengths and masses, angles q1, q2 (from the
                                downward vertical; q2 absolute) and their canonical momenta:
                                H = (p1^2 + 2 p2^2 - 2 p1 p2 cos(q1 - q2))
                                    / (2 (1 + sin^2(q1 - q2))) - 2 g cos q1 - g cos q2,
                                theta = [g], g = 1; omega_max = sqrt(g (2 + sqrt 2)).
                                Starts: q_i, p_i uniform in [-0.8, 0.8], kept when the energy
                                above the minimum -3 g is in [0.05, 0.6] (so |q1| <= 0.80,
                                |q2| <= 1.16 rad at all times: bounded, mildly nonlinear)

The double pendulum's H is NOT separable (its kinetic energy depends on q1 - q2): it is outside
the class of csympnet's Hamiltonian-library core (H = p^T W p / 2 + V(q) with a constant W) and
is there to see what that core, and the default core choice, do on such data. Its dynamics are
dq/dt = dH/dp, dp/dt = -dH/dq - gamma p: the system supplies this field (make_system's
"field") and the data RK4 and the oracle integrate it instead of M^-1 p and grad V. It is not
in the default plan (the plan cycles through its system list, so adding a system there would
move every case of every seed; with it left out the default plans and data are those of
before): name it in --systems, or give --systems all. It has no violation cases.

The dissipation -gamma p acts on the canonical momenta, so every flow is conformally
symplectic. Trajectories are integrated with a fixed-substep classical RK4 (omega_max * substep
= 1e-3 by default); for the first case of each system the data are generated again with half the
substep and the largest difference (relative to each coordinate's spread) is reported.

Strata (every case has one value of each; values are assigned in balanced, shuffled order):

    gamma ratio  gamma = r * omega_max (omega_max: the fastest linear frequency about the
                 equilibrium), r log-uniform in one decade: "r<0.01", "0.01<=r<0.1", "r>=0.1"
    units        "natural", or "units": q_file = s_q q + offset, p_file = s_p p with s_q, s_p
                 log-uniform in [1e-3, 1e3], an offset of 2-5 spreads per coordinate, and for half
                 of these cases time t_file = c t with c log-uniform in [1e-2, 1e2] (the true
                 rate in the file's units is then gamma / c)
    shape        "long" (one trajectory of 300-2000 samples over 20-30 fastest periods, or over
                 5-7.5 decay times 1/gamma where that is shorter), "few" (3-5 trajectories of
                 100-300 samples), "many" (30-100 trajectories of 8-20 samples); --quick keeps
                 them small (<= 400, 3 x <= 150, <= 40 x <= 12 samples; d <= 4)
    steps        "regular" (h0), "irregular" (each step uniform in [0.5, 1.5] h0), "gaps" (regular
                 with ~10% of the samples dropped at random); h0 gives 10-40 samples per fastest
                 period (log-uniform)
    sigma        0, 1e-3, 1e-2, 5e-2: Gaussian measurement noise on every stored coordinate, std
                 sigma times that coordinate's std over the file (the dynamics are noise-free)

Violation cases (--violations; without it the case plan and data are as described above):
the same strata plus "violation", balanced like the others, one of the kinds below
(not for double-pendulum)

    nonuniform-1.5, nonuniform-3, nonuniform-30  (toda, fpu-alpha, fpu-beta, henon-heiles,
                 coupled-pendulums) dp/dt = -grad V - C p, C = M V diag(rates) V^T with V the
                 modes of the linearisation at q = 0 (K V = M V diag(freq^2), V^T M V = I,
                 K by central differences of grad), so that each linear mode a obeys
                 a'' + rate_i a' + freq_i^2 a = 0; the rates are spread geometrically from gamma
                 to 1.5 / 3 / 30 gamma and assigned to the modes in a seeded random order
    coulomb-0.2, coulomb-0.5, coulomb-0.9  (d = 1 systems) -gamma_v p - mu tanh(p / eps),
                 eps = 1e-3 omega A0; the dry friction's equivalent rate 4 mu / (pi omega A0) is
                 20 / 50 / 90 % of gamma = gamma_v + gamma_c. omega A0 = sqrt(2 E0), E0 the
                 median initial energy above the potential's minimum
    quadratic-drag  (d = 1) -gamma_v p - c |p| p, the drag's equivalent rate c (8 / (3 pi))
                 omega A0 = gamma / 2, gamma_v = gamma / 2
    periodic-force  (any system) -grad V - gamma p + f0_i cos(Omega t + phi_i) on every p_i,
                 Omega = omega_max U(0.6, 0.9) (redrawn to stay >= 5% from every linear mode
                 frequency when possible), f0_i = 0.05 A0_i m_i min_k |freq_k^2 - Omega^2| with
                 A0_i half the spread of q_i in the same data without the force
    drifting-equilibrium  (all but softened-central) grad V evaluated at q - v t, |v_i| times
                 the longest trajectory's duration = 20% of the spread of q_i (as above)
    energy-gain  (any system) gamma = -r omega_max < 0; every trajectory is cut to at most
                 max(6, 2 ln 4 / |gamma| / h0 + 1) samples (linear amplitude growth <= 4)

with t the time since each trajectory's start. These are integrated by the same RK4 with the
right-hand side dp/dt = f(t, q, p); the integrator check is made on the first case of each
violation kind. results.json records per case "violation": kind, size, parameters, rates in
the file's time units (coulomb, drag: gamma_viscous and the equivalent parts; nonuniform:
modal_rates; energy gain: the negative gamma), gamma_reference (the case's gamma_true: the drawn
gamma, i.e. the equivalent total at A0, or the mean modal rate for nonuniform) and
gamma_reference_range ([min, max] modal rate for nonuniform, else the point). Errors are
relative to |gamma_reference|; "confident wrong" on a violation case: identified with an
interval outside gamma_reference_range (no error threshold).

Each case is a trajectories CSV (`traj,t,q1..qd,p1..pd`, numbers written with repr) that is
given to these methods:

    csympnet  `csympnet fit DATA --out DIR -q [--fit-args]`; reads DIR/report.json (gamma_hat,
              gamma_ci_low/high, identified, verdict, checks). Exit 0: identified; exit 4: "not
              identified"; exit 5: "model rejected" (a model check failed; both counted apart,
              never as a wrong number); anything else, or the timeout: failed. Also recorded:
              report.json "choices"."core"."type" (core_type: which core the fit chose) and,
              when present, its "hamiltonian" object (the fitted terms).
    csympnet_library  (--library only) `csympnet fit DATA --out DIR -q --core library
              [--fit-args]`: the same data with the Hamiltonian-library core forced, read and
              counted exactly as csympnet (output in cases/<id>/csympnet_library/). Only for
              d <= 4 (LIBRARY_MAX_D), where the library core is one of fit's default
              candidates; beyond, its fit takes minutes and the case is marked skipped.
    sindy     sparse regression of dp/dt: derivatives and smoothed states from a local cubic
              fit (7 samples, tricube weights, any spacing) per trajectory, then STLSQ
              (threshold 0.01 on unit-scaled columns and targets, ridge 1e-10, 10 passes) on a
              library of a constant, monomials of degree 1-3 in the standardized (q, p), and
              sin/cos of each q_i. The p_i term of the dp_i/dt equation is never thresholded
              (the model class has a damping term). When the library would have more than
              min(500, samples/3) columns, degree-2/3 monomials are kept in order of how many
              sites they span (a locality prior). gamma_hat = -mean_i (coefficient of p_i in
              dp_i/dt), in the file's time units. No interval. These settings were chosen once,
              on cases drawn with another seed, and are the same for every case.
    oracle    the true form of the system with its potential parameters and gamma unknown,
              fitted by Levenberg-Marquardt (finite-difference Jacobian) to one-step predictions
              (RK4 over each observed step), residuals scaled by each coordinate's std. It is
              given the true unit scales, offsets and time scale, i.e. it fits in natural units.
              Start: the potential parameters at the truth times exp(0.2 z), gamma at
              0.05 omega_max. Interval: gamma +- 1.96 sqrt(s^2 (J^T J)^-1), the Gauss-Newton
              covariance. It is the floor the others can be measured against (with noise, the
              noisy start of each step makes it biased: errors in variables).

Per case: relative error |gamma_hat - gamma| / gamma, whether the 95% interval covers gamma, the
interval's width / gamma, identified or not, wall seconds. "Confident wrong": identified, the
interval misses gamma and the relative error exceeds 0.1. The tables (stdout, DIR/summary.md)
give, per stratum value and method: n, median / 90th percentile / worst relative error (over the
cases with a number), coverage (covering / cases with an interval), not identified, rejected,
failed, confident wrong, relative error > 0.1, median wall seconds. With csympnet results, also
its model checks (report.json "checks": measured_momenta, dissipation, linear_damping,
one_rate, residuals; a check fails when "passed" is false): on valid cases the false-alarm rate of each check and of
any check (failed / applicable, failed / all), overall and per sigma and shape; on violation
cases, per kind and size, the detection rate of each check and of any check, the shares
rejected / not identified / identified, failed, and the confident wrong count, with those cases
listed; and csympnet's verdict counts (identified / not identified / rejected / failed) per
stratum value. With csympnet or csympnet_library results, a core-choice table: per method and
system, how many cases' report.json say choices.core.type == "library" (for csympnet: how
often the library core won its choice), the other core types, and those with no report or no
core in it. DIR/results.json holds every case's
configuration (system, parameters, seed, strata, true gamma, paths) and every method's result
(csympnet's and csympnet_library's with verdict, checks, core_type and "hamiltonian"), and the
core-choice counts ("core_choice").
The case files stay in DIR/cases/<id>/data.csv, csympnet's output in DIR/cases/<id>/csympnet/
(csympnet_library's in DIR/cases/<id>/csympnet_library/).

Ctrl-C (SIGINT) or SIGTERM stops at once: running fits are killed, the finished cases are
written (marked interrupted) and the exit status is 128 + the signal. Otherwise the exit status
is 0, or 1 if a case could not be generated.
"""
import argparse
import concurrent.futures as cf
import datetime
import itertools
import json
import math
import os
import platform
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

RATIO_STRATA = ["r<0.01", "0.01<=r<0.1", "r>=0.1"]
RATIO_DECADE = {"r<0.01": (-3.0, -2.0), "0.01<=r<0.1": (-2.0, -1.0), "r>=0.1": (-1.0, 0.0)}
UNITS_STRATA = ["natural", "units"]
SHAPE_STRATA = ["long", "few", "many"]
STEPS_STRATA = ["regular", "irregular", "gaps"]
SIGMA_STRATA = [0.0, 1e-3, 1e-2, 5e-2]
METHODS = ["csympnet", "csympnet_library", "csympnet_positions", "csympnet_differenced", "sindy",
           "oracle"]
CORE_CHOICE_METHODS = ["csympnet", "csympnet_library"]  # the core-choice table
LIBRARY_MAX_D = 4  # csympnet_library runs up to this d (the library core's default limit)
VIOLATION_STRATA = ["nonuniform-1.5", "nonuniform-3", "nonuniform-30", "coulomb-0.2",
                    "coulomb-0.5", "coulomb-0.9", "quadratic-drag", "periodic-force",
                    "drifting-equilibrium", "energy-gain"]
CHECK_NAMES = ["measured_momenta", "dissipation", "linear_damping", "one_rate", "residuals"]
VERDICTS = ["identified", "not identified", "rejected", "failed"]

GEN_OMEGA_DT = 1e-3      # omega_max * RK4 substep when generating data
ORACLE_OMEGA_DT = 1e-2   # omega_max * RK4 substep inside the oracle's one-step predictions
SG_WINDOW = 7            # samples in the local polynomial fit (sindy)
SG_DEGREE = 3
STLSQ_THRESHOLD = 1e-2
STLSQ_RIDGE = 1e-10
STLSQ_PASSES = 10
LIBRARY_CAP = 500


class Interrupted(Exception):
    pass


STOP = threading.Event()


def check_stop():
    if STOP.is_set():
        raise Interrupted()


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


# ----------------------------------------------------------------------------------------------
# RK4


def rk4(grad, theta, minv, gamma, q, p, dt, n):
    """n classical RK4 steps of size dt (a scalar or one per column) of
    dq/dt = minv p, dp/dt = -grad(q) - gamma p."""
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


# ----------------------------------------------------------------------------------------------
# Case plan and data generation


def plan(n, seed, systems):
    rng = np.random.default_rng(seed)

    def balanced(values):
        vals = [values[i % len(values)] for i in range(n)]
        return [vals[i] for i in rng.permutation(n)]
    cols = [balanced(systems), balanced(RATIO_STRATA), balanced(UNITS_STRATA),
            balanced(SHAPE_STRATA), balanced(STEPS_STRATA), balanced(SIGMA_STRATA)]
    cases = []
    for i, (system, ratio, units, shape, steps, sigma) in enumerate(zip(*cols)):
        cases.append({"index": i, "id": f"c{i:03d}-{system}", "system": system, "seed": [seed, i],
                      "strata": {"ratio": ratio, "units": units, "shape": shape, "steps": steps,
                                 "sigma": sigma}})
    return cases


def plan_violations(n, seed, systems):
    """Violation cases: the strata of plan() plus "violation" (VIOLATION_STRATA, balanced);
    each family's systems (VIOLATION_SYSTEMS within --systems) are taken in turn, shuffled."""
    rng = np.random.default_rng([seed, 2])
    kinds = [k for k in VIOLATION_STRATA
             if any(x in systems for x in VIOLATION_SYSTEMS[violation_family(k)[0]])]
    if not kinds:
        raise ValueError("no violation kind has a system among --systems")

    def balanced(values):
        vals = [values[i % len(values)] for i in range(n)]
        return [vals[i] for i in rng.permutation(n)]
    cols = [balanced(kinds), balanced(RATIO_STRATA), balanced(UNITS_STRATA),
            balanced(SHAPE_STRATA), balanced(STEPS_STRATA), balanced(SIGMA_STRATA)]
    pools = {}
    for fam, names in VIOLATION_SYSTEMS.items():
        allowed = [x for x in names if x in systems]
        pools[fam] = [allowed[i] for i in rng.permutation(len(allowed))] if allowed else []
    used = {}
    cases = []
    for i, (kind, ratio, units, shape, steps, sigma) in enumerate(zip(*cols)):
        fam = violation_family(kind)[0]
        pool = pools[fam]
        system = pool[used.get(fam, 0) % len(pool)]
        used[fam] = used.get(fam, 0) + 1
        cases.append({"index": i, "id": f"v{i:03d}-{kind}-{system}", "system": system,
                      "seed": [seed, 100000 + i],
                      "strata": {"violation": kind, "ratio": ratio, "units": units,
                                 "shape": shape, "steps": steps, "sigma": sigma}})
    return cases


def log_uniform(rng, lo, hi):
    return math.exp(rng.uniform(math.log(lo), math.log(hi)))


def generate(case, quick, check_integrator):
    """Draw the case's parameters, integrate, transform units, add noise. Returns (data, info):
    data: list of (t_file, Z_file (n, 2d)) per trajectory; info: what results.json records and
    what the oracle needs (natural-unit transform)."""
    rng = np.random.default_rng(case["seed"])
    st = case["strata"]
    s = make_system(case["system"], rng, quick)
    d = s["d"]
    omega = s["omega_max"]
    lo, hi = RATIO_DECADE[st["ratio"]]
    r = 10.0 ** rng.uniform(lo, hi)
    gamma = r * omega
    kind = st.get("violation")
    if kind == "energy-gain":
        gamma = -gamma
    g_abs = abs(gamma)
    spp = log_uniform(rng, 10.0, 40.0)
    period = 2.0 * math.pi / omega
    h0 = period / spp
    if st["shape"] == "long":
        # >= ~20 fastest periods, or 5 decay times 1/gamma when these are shorter
        duration = min(20.0 * period, max(5.0 / g_abs, 2.0 * period)) * rng.uniform(1.0, 1.5)
        cap = 400 if quick else 2000
        lengths = [int(min(cap, max(300, round(duration / h0))))]
    elif st["shape"] == "few":
        m = int(rng.integers(3, 4 if quick else 6))
        lengths = [int(rng.integers(100, 151 if quick else 301)) for _ in range(m)]
    else:
        m = int(rng.integers(30, 41 if quick else 101))
        lengths = [int(rng.integers(8, 13 if quick else 21)) for _ in range(m)]
    if kind == "energy-gain":  # the amplitude grows as exp(|gamma| t / 2): at most 4 times
        n_cap = max(6, int(2.0 * math.log(4.0) / g_abs / h0) + 1)
        lengths = [min(n, n_cap) for n in lengths]
    if st["steps"] == "gaps":  # generate more so that the counts above hold after the drop
        kept = lengths
        lengths = [max(n + 1, int(round(n / 0.9))) for n in lengths]
    m = len(lengths)
    K = max(lengths) - 1
    steps = np.zeros((m, K))
    for j, n in enumerate(lengths):
        if st["steps"] == "irregular":
            steps[j, :n - 1] = h0 * rng.uniform(0.5, 1.5, n - 1)
        else:
            steps[j, :n - 1] = h0
    q0, p0 = s["init"](rng, m)
    substep = GEN_OMEGA_DT / omega
    dpdt, vinfo = None, None
    if kind is not None:
        dpdt, vinfo = violation_setup(kind, s, gamma, q0, p0, steps, substep,
                                      np.random.default_rng(case["seed"] + [2]))
    Q, P = integrate(s, gamma, q0, p0, steps, substep, dpdt)
    check = None
    if check_integrator:
        Q2, P2 = integrate(s, gamma, q0, p0, steps, substep / 2, dpdt)
        diffs, spreads, norms = [], [], []
        for j, n in enumerate(lengths):
            za = np.concatenate([Q[:n, :, j], P[:n, :, j]], axis=1)
            zb = np.concatenate([Q2[:n, :, j], P2[:n, :, j]], axis=1)
            diffs.append(np.abs(za - zb))
            norms.append(np.abs(zb).max(axis=1))
            spreads.append(zb)
        allz = np.concatenate(spreads)
        dif = np.concatenate(diffs)
        sd = allz.std(axis=0)
        sd[sd == 0] = 1.0
        check = {"substep": substep, "max_abs_diff": float(dif.max()),
                 "max_diff_over_coordinate_std": float((dif / sd).max()),
                 "max_diff_over_state_max_norm": float(max(
                     (df.max(axis=1) / np.maximum(nm, 1e-300)).max()
                     for df, nm in zip(diffs, norms)))}
    if not (np.all(np.isfinite(Q)) and np.all(np.isfinite(P))) or np.abs(Q).max() > 1e3:
        raise RuntimeError(f"{case['id']}: a trajectory left the bounded region")
    # natural-unit trajectories, gaps
    trajs = []
    for j, n in enumerate(lengths):
        t = np.concatenate([[0.0], np.cumsum(steps[j, :n - 1])])
        z = np.concatenate([Q[:n, :, j], P[:n, :, j]], axis=1)
        if st["steps"] == "gaps":
            drop = rng.choice(np.arange(1, n), size=n - kept[j], replace=False)
            keep = np.setdiff1d(np.arange(n), drop)
            t, z = t[keep], z[keep]
        trajs.append((t, z))
    allz = np.concatenate([z for _, z in trajs])
    # units
    if st["units"] == "units":
        s_q = log_uniform(rng, 1e-3, 1e3)
        s_p = log_uniform(rng, 1e-3, 1e3)
        qstd = allz[:, :d].std(axis=0)
        qstd = np.where(qstd > 0, qstd, 1.0)
        offset = s_q * qstd * rng.uniform(2.0, 5.0, d) * np.sign(rng.uniform(-1, 1, d))
        c = log_uniform(rng, 1e-2, 1e2) if rng.uniform() < 0.5 else 1.0
    else:
        s_q, s_p, offset, c = 1.0, 1.0, np.zeros(d), 1.0
    files = []
    for t, z in trajs:
        zf = np.concatenate([s_q * z[:, :d] + offset, s_p * z[:, d:]], axis=1)
        files.append((c * t, zf))
    sigma = st["sigma"]
    if sigma > 0:
        sd = np.concatenate([z for _, z in files]).std(axis=0)
        files = [(t, z + sigma * sd * rng.standard_normal(z.shape)) for t, z in files]
    info = {
        "system": s["name"], "d": d, "theta": dict(zip(s["theta_names"], s["theta"])),
        "masses": s["masses"], "omega_max": omega, "r": r, "gamma_natural": gamma,
        "gamma_true": gamma / c, "samples_per_fastest_period": spp, "h0_natural": h0,
        "h0_file": h0 * c, "n_traj": m, "samples": int(sum(len(t) for t, _ in files)),
        "samples_per_traj": [int(len(t)) for t, _ in files], "substep_natural": substep,
        "units": {"s_q": s_q, "s_p": s_p, "q_offset": [float(x) for x in offset], "time_scale": c},
        "integrator_check": check,
    }
    if vinfo is not None:
        info["violation"] = violation_record(kind, vinfo, gamma, c)
        info["gamma_true"] = info["violation"]["gamma_reference"]
    return files, info, s


def computed_momenta(files, d, how):
    """The momenta a user without a momentum sensor would write: the p columns replaced by
    numpy.gradient of the (noisy) q columns, or by a Savitzky-Golay derivative (window 11,
    cubic, at the trajectory's median step; numpy.gradient where a trajectory is shorter)."""
    from scipy.signal import savgol_filter
    out = []
    for t, z in files:
        z = z.copy()
        for i in range(d):
            q = z[:, i]
            if len(t) < 2:
                v = np.zeros_like(q)
            elif how == "savgol" and len(t) >= 11:
                v = savgol_filter(q, 11, 3, deriv=1, delta=float(np.median(np.diff(t))))
            else:
                v = np.gradient(q, t)
            z[:, d + i] = v
        out.append((t, z))
    return out


def write_csv(path, files, d, positions_only=False):
    names = [f"q{i + 1}" for i in range(d)] + ([] if positions_only
                                               else [f"p{i + 1}" for i in range(d)])
    lines = ["traj,t," + ",".join(names)]
    for j, (t, z) in enumerate(files):
        zz = z[:, :d] if positions_only else z
        for k in range(len(t)):
            lines.append(f"{j}," + ",".join(repr(float(x)) for x in itertools.chain([t[k]], zz[k])))
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


# ----------------------------------------------------------------------------------------------
# Peer 1: SINDy-style sparse regression


def local_poly(t, z, window, degree):
    """Weighted local polynomial fit around every sample (any spacing): smoothed states and
    their time derivatives."""
    n = len(t)
    w_n = min(window, n)
    deg = min(degree, w_n - 2)
    start = np.clip(np.arange(n) - w_n // 2, 0, n - w_n)
    idx = start[:, None] + np.arange(w_n)[None, :]
    tau = t[idx] - t[:, None]
    scale = np.abs(tau).max(axis=1)
    u = tau / scale[:, None]
    w = (1.0 - (np.abs(u) / 1.2) ** 3) ** 3
    V = u[:, :, None] ** np.arange(deg + 1)[None, None, :]
    A = V * np.sqrt(w)[:, :, None]
    B = z[idx] * np.sqrt(w)[:, :, None]
    At = np.transpose(A, (0, 2, 1))
    coef = np.linalg.solve(At @ A, At @ B)  # (n, deg + 1, 2d)
    return coef[:, 0, :], coef[:, 1, :] / scale[:, None]


def library_terms(d, budget):
    """Monomials of degree 2 and 3 in the 2d variables (q first, then p), ordered by span of
    sites then degree, cut at budget."""
    site = list(range(d)) + list(range(d))
    terms = []
    for deg in (2, 3):
        for combo in itertools.combinations_with_replacement(range(2 * d), deg):
            sites = [site[v] for v in combo]
            terms.append((max(sites) - min(sites), deg, combo))
    terms.sort()
    return [c for _, _, c in terms[:max(0, budget)]]


def sindy(files, d, threshold=None, ridge=None, window=None):
    threshold = STLSQ_THRESHOLD if threshold is None else threshold
    ridge = STLSQ_RIDGE if ridge is None else ridge
    window = SG_WINDOW if window is None else window
    zs, dzs = [], []
    for t, z in files:
        zs_, dz_ = local_poly(np.asarray(t), np.asarray(z), window, SG_DEGREE)
        zs.append(zs_)
        dzs.append(dz_)
    Z = np.concatenate(zs)
    Y = np.concatenate(dzs)[:, d:]
    N = Z.shape[0]
    mu = Z.mean(axis=0)
    sd = Z.std(axis=0)
    sd = np.where(sd > 0, sd, 1.0)
    U = (Z - mu) / sd
    cap = min(LIBRARY_CAP, N // 3)
    cols = [np.ones(N)] + [U[:, v] for v in range(2 * d)]
    cols += [np.sin(Z[:, i]) for i in range(d)] + [np.cos(Z[:, i]) for i in range(d)]
    monos = library_terms(d, cap - len(cols))
    for combo in monos:
        cols.append(np.prod(U[:, list(combo)], axis=1))
    Theta = np.stack(cols, axis=1)
    rms = np.sqrt((Theta ** 2).mean(axis=0))
    keep_col = rms > 1e-300
    Theta = Theta[:, keep_col] / rms[keep_col]
    col_index = np.cumsum(keep_col) - 1  # original column -> kept column
    # Least squares on R of Theta = Q R (better conditioned than normal equations); the ridge
    # enters as extra rows sqrt(ridge N) I.
    Qm, R = np.linalg.qr(Theta)
    ncol = Theta.shape[1]
    sq_ridge = math.sqrt(ridge * N)
    gammas = []
    n_active = []
    for i in range(d):
        check_stop()
        y = Y[:, i]
        ys = math.sqrt(float((y ** 2).mean())) or 1.0
        c = Qm.T @ (y / ys)
        if not keep_col[1 + d + i]:
            raise RuntimeError(f"p{i + 1} is constant over the file")
        protect = col_index[1 + d + i]
        active = np.ones(ncol, dtype=bool)
        xi = np.zeros(ncol)
        for _ in range(STLSQ_PASSES):
            a = np.flatnonzero(active)
            A = np.vstack([R[:, a], sq_ridge * np.eye(len(a))])
            b = np.concatenate([c, np.zeros(len(a))])
            xi[:] = 0.0
            xi[a] = np.linalg.lstsq(A, b, rcond=None)[0]
            small = np.abs(xi) < threshold
            small[protect] = False
            new_active = active & ~small
            if np.array_equal(new_active, active):
                break
            active = new_active
        # dp_i/dt ~ ys * xi_p * (p_i - mu) / (sd_p * rms); rms of a centred standardized column is 1
        coef_p = ys * xi[protect] / (sd[d + i] * rms[1 + d + i])
        gammas.append(-coef_p)
        n_active.append(int(active.sum()))
    return float(np.mean(gammas)), {"per_coordinate": [float(g) for g in gammas],
                                    "library_columns": int(Theta.shape[1]),
                                    "active_terms": n_active}


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


# ----------------------------------------------------------------------------------------------
# csympnet

CHILDREN = set()
CHILDREN_LOCK = threading.Lock()


def kill_group(p, sig):
    try:
        os.killpg(p.pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def run_child(cmd, timeout):
    check_stop()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    with CHILDREN_LOCK:
        CHILDREN.add(p)
    timed_out = False
    try:
        try:
            out, err = p.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            timed_out = True
            kill_group(p, signal.SIGKILL)
            out, err = p.communicate()
    finally:
        with CHILDREN_LOCK:
            CHILDREN.discard(p)
    check_stop()
    return p.returncode, out, err, timed_out


def num(v):
    """a finite JSON number as float, else None"""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    return float(v) if math.isfinite(float(v)) else None


def parse_checks(checks):
    """report.json's "checks" (one object per assumption) as a list of dicts, or None"""
    if not isinstance(checks, list):
        return None
    out = []
    for ch in checks:
        if not isinstance(ch, dict):
            continue
        rec = {"name": str(ch.get("name", "?")),
               "applicable": ch.get("applicable") if isinstance(ch.get("applicable"), bool)
               else None,
               "passed": ch.get("passed") if isinstance(ch.get("passed"), bool) else None}
        for k in ("statistic", "p_value", "alpha", "effect", "effect_threshold",
                  "detectable_effect"):
            rec[k] = num(ch.get(k))
        for k in ("assumption", "sentence"):
            rec[k] = ch.get(k) if isinstance(ch.get(k), str) else None
        rec["details"] = ch.get("details")
        out.append(rec)
    return out


def core_type(rep):
    """report.json "choices"."core"."type" (a core given as a string such as "la:5:20":
    the part before the first ':'), or None"""
    core = (rep.get("choices") or {}).get("core") if isinstance(rep.get("choices"), dict) \
        else None
    if isinstance(core, dict):
        t = core.get("type")
        return t if isinstance(t, str) else None
    if isinstance(core, str) and core:
        return core.split(":", 1)[0]
    return None


def run_csympnet(exe, data, outdir, extra, timeout):
    cmd = [exe, "fit", data, "--out", outdir, "-q", "--no-figures", *extra]
    t0 = time.monotonic()
    rc, out, err, timed_out = run_child(cmd, timeout)
    res = {"seconds": time.monotonic() - t0, "returncode": rc, "command": cmd,
           "stdout_tail": out.strip().splitlines()[-1] if out.strip() else ""}
    last_err = err.strip().splitlines()[-1] if err.strip() else ""
    if timed_out:
        res.update(status="failed", reason=f"timeout after {timeout} s")
        return res
    rep_path = os.path.join(outdir, "report.json")
    rep = None
    if rc in (0, 4, 5) and os.path.exists(rep_path):
        try:
            with open(rep_path) as f:
                rep = json.load(f)
        except (OSError, ValueError) as e:
            res.update(status="failed", reason=f"unreadable report.json: {e}")
            return res
    if rep is not None:
        res["verdict"] = rep.get("verdict")
        res["checks"] = parse_checks(rep.get("checks"))
        res["core_type"] = core_type(rep)
        if isinstance(rep.get("hamiltonian"), dict):
            res["hamiltonian"] = rep["hamiltonian"]
    if rc == 5 and rep is not None:  # model rejected: a verdict, counted apart
        failed = [ch.get("sentence") or ch["name"] for ch in res["checks"] or []
                  if ch["passed"] is False]
        res.update(status="rejected", identified=False,
                   reason="; ".join(failed) or rep.get("not_identified_reason", last_err),
                   gamma_hat=num(rep.get("gamma_hat")))
        return res
    if rc == 4:
        res.update(status="not_identified", identified=False,
                   reason=(rep or {}).get("not_identified_reason", last_err),
                   gamma_hat=num((rep or {}).get("gamma_hat")))
        return res
    if rc != 0 or rep is None:
        res.update(status="failed", reason=last_err or f"exit {rc}, no report.json")
        return res
    g = num(rep.get("gamma_hat"))
    identified = rep.get("identified", g is not None)
    res.update(gamma_hat=g, ci_low=num(rep.get("gamma_ci_low")),
               ci_high=num(rep.get("gamma_ci_high")), identified=bool(identified))
    if not identified:
        res.update(status="not_identified", reason=rep.get("not_identified_reason", ""))
    elif g is None:
        res.update(status="failed", reason="exit 0 but gamma_hat is not a number")
    else:
        res["status"] = "ok"
    return res


# ----------------------------------------------------------------------------------------------
# One case


def score(res, gamma):
    if res.get("status") != "ok":
        return res
    g = res.get("gamma_hat")
    res["rel_err"] = abs(g - gamma) / gamma
    lo, hi = res.get("ci_low"), res.get("ci_high")
    if lo is not None and hi is not None:
        res["covers"] = bool(lo <= gamma <= hi)
        res["rel_width"] = (hi - lo) / gamma
        res["confident_wrong"] = (not res["covers"]) and res["rel_err"] > 0.1
    else:
        res["covers"] = None
        res["rel_width"] = None
        res["confident_wrong"] = None
    return res


def score_violation(res, v):
    """Violation cases: the relative error against gamma_reference; an interval that lies
    outside gamma_reference_range is a confident answer on violated data (confident_wrong)."""
    if res.get("status") != "ok":
        return res
    gamma = v["gamma_reference"]
    ref_lo, ref_hi = v["gamma_reference_range"]
    g = res.get("gamma_hat")
    res["rel_err"] = abs(g - gamma) / abs(gamma)
    lo, hi = res.get("ci_low"), res.get("ci_high")
    if lo is not None and hi is not None:
        res["covers"] = bool(lo <= gamma <= hi)
        res["rel_width"] = (hi - lo) / abs(gamma)
        res["confident_wrong"] = bool(hi < ref_lo or lo > ref_hi)
    else:
        res["covers"] = None
        res["rel_width"] = None
        res["confident_wrong"] = None
    return res


def run_case(case, args, check_integrator, exe, extra):
    check_stop()
    cdir = os.path.join(args.out, "cases", case["id"])
    os.makedirs(cdir, exist_ok=True)
    t0 = time.monotonic()
    files, info, s = generate(case, args.quick, check_integrator)
    if args.momenta != "given":
        files = computed_momenta(files, info["d"], args.momenta)
    info["momenta"] = args.momenta
    case.update(info)
    case["generate_seconds"] = time.monotonic() - t0
    data = os.path.join(cdir, "data.csv")
    write_csv(data, files, info["d"])
    case["paths"] = {"data": os.path.relpath(data, args.out)}
    gamma = info["gamma_true"]
    scorer = score
    if "violation" in info:
        def scorer(res, gamma, v=info["violation"]):
            return score_violation(res, v)
    methods = {}
    if args.observed:
        # The same record as a user with a position sensor alone has it, and as one who
        # differences it (centred differences, numpy.gradient).
        variants = {"positions": (files, True),
                    "differenced": (computed_momenta(files, info["d"], "gradient"), False)}
        for name, (vfiles, positions_only) in variants.items():
            path = os.path.join(cdir, f"data_{name}.csv")
            write_csv(path, vfiles, info["d"], positions_only)
            case["paths"][f"data_{name}"] = os.path.relpath(path, args.out)
            if args.only_peers:
                continue
            outdir = os.path.join(cdir, f"csympnet_{name}")
            if os.path.isdir(outdir):
                shutil.rmtree(outdir)
            # The differenced momenta as a user would use them: kept (the default sets them
            # aside and gives csympnet_positions' answer).
            more = extra + (["--derived-momenta", "use"] if name == "differenced" else [])
            methods[f"csympnet_{name}"] = scorer(
                run_csympnet(exe, path, outdir, more, args.timeout), gamma)
    if args.skip_peers:
        methods["sindy"] = {"status": "skipped"}
        methods["oracle"] = {"status": "skipped"}
    else:
        t0 = time.monotonic()
        try:
            g, extra_s = sindy(files, info["d"])
            res = {"status": "ok" if math.isfinite(g) else "failed", "gamma_hat": g,
                   "identified": True, "ci_low": None, "ci_high": None, "extra": extra_s}
        except Interrupted:
            raise
        except Exception as e:  # a peer that breaks on a case is a failure of that peer
            res = {"status": "failed", "reason": f"{type(e).__name__}: {e}"}
        res["seconds"] = time.monotonic() - t0
        methods["sindy"] = scorer(res, gamma)
        t0 = time.monotonic()
        try:
            o = oracle(files, info, s, np.random.default_rng(case["seed"] + [1]))
            res = {"status": "ok" if math.isfinite(o["gamma_hat"]) else "failed", "identified": True,
                   **o}
        except Interrupted:
            raise
        except Exception as e:
            res = {"status": "failed", "reason": f"{type(e).__name__}: {e}"}
        res["seconds"] = time.monotonic() - t0
        methods["oracle"] = scorer(res, gamma)
    if args.only_peers:
        methods["csympnet"] = {"status": "skipped"}
        if args.library:
            methods["csympnet_library"] = {"status": "skipped"}
    else:
        outdir = os.path.join(cdir, "csympnet")
        if os.path.isdir(outdir):
            shutil.rmtree(outdir)
        case["paths"]["csympnet_out"] = os.path.relpath(outdir, args.out)
        methods["csympnet"] = scorer(run_csympnet(exe, data, outdir, extra, args.timeout), gamma)
        if args.library and info["d"] > LIBRARY_MAX_D:
            methods["csympnet_library"] = {"status": "skipped"}
        elif args.library:  # the same data, the Hamiltonian-library core forced
            outdir = os.path.join(cdir, "csympnet_library")
            if os.path.isdir(outdir):
                shutil.rmtree(outdir)
            case["paths"]["csympnet_library_out"] = os.path.relpath(outdir, args.out)
            methods["csympnet_library"] = scorer(
                run_csympnet(exe, data, outdir, ["--core", "library"] + extra, args.timeout),
                gamma)
    case["methods"] = methods
    return case


# ----------------------------------------------------------------------------------------------
# Statistics and tables


def fmt(x, kind="e"):
    if x is None:
        return "n/a"
    if kind == "s":
        return f"{x:.2f}" if x < 100 else f"{x:.0f}"
    return f"{x:.1e}"


def method_stats(cases, method):
    rs = [c["methods"][method] for c in cases if method in c.get("methods", {})]
    rs = [r for r in rs if r.get("status") != "skipped"]
    if not rs:
        return None
    errs = np.array([r["rel_err"] for r in rs if r.get("status") == "ok"])
    with_ci = [r for r in rs if r.get("status") == "ok" and r.get("covers") is not None]
    secs = [r["seconds"] for r in rs if "seconds" in r]
    return {
        "n": len(rs),
        "median": float(np.median(errs)) if errs.size else None,
        "p90": float(np.percentile(errs, 90)) if errs.size else None,
        "worst": float(errs.max()) if errs.size else None,
        "covered": sum(1 for r in with_ci if r["covers"]),
        "with_interval": len(with_ci),
        "coverage": (sum(1 for r in with_ci if r["covers"]) / len(with_ci)) if with_ci else None,
        "not_identified": sum(1 for r in rs if r.get("status") == "not_identified"),
        "rejected": sum(1 for r in rs if r.get("status") == "rejected"),
        "failed": sum(1 for r in rs if r.get("status") == "failed"),
        "confident_wrong": (sum(1 for r in rs if r.get("confident_wrong")) if method != "sindy"
                            else None),
        "err_gt_0.1": int((errs > 0.1).sum()),
        "median_seconds": float(np.median(secs)) if secs else None,
    }


GROUPS = [("all", lambda c: "all"), ("system", lambda c: c["system"]),
          ("gamma ratio", lambda c: c["strata"]["ratio"]),
          ("units", lambda c: c["strata"]["units"]), ("shape", lambda c: c["strata"]["shape"]),
          ("steps", lambda c: c["strata"]["steps"]),
          ("sigma", lambda c: f"{c['strata']['sigma']:g}")]


def groups_for(cases):
    """GROUPS, with the violation stratum after "all" when there are violation cases"""
    if any("violation" in c["strata"] for c in cases):
        return GROUPS[:1] + [("violation", lambda c: c["strata"].get("violation", "none"))] \
            + GROUPS[1:]
    return GROUPS


def group_values(gname, key, cases):
    values = []
    for c in cases:
        if key(c) not in values:
            values.append(key(c))
    order = {"violation": VIOLATION_STRATA, "system": SYSTEM_NAMES,
             "gamma ratio": RATIO_STRATA, "units": UNITS_STRATA,
             "shape": SHAPE_STRATA, "steps": STEPS_STRATA,
             "sigma": [f"{s:g}" for s in SIGMA_STRATA]}.get(gname)
    if order:
        values.sort(key=lambda v: order.index(v) if v in order else len(order))
    return values


def summarize(cases):
    out = {}
    for gname, key in groups_for(cases):
        out[gname] = {v: {m: method_stats([c for c in cases if key(c) == v], m) for m in METHODS}
                      for v in group_values(gname, key, cases)}
    return out


def tables(summary):
    lines = []
    head = ("| {} | method | n | median | p90 | worst | coverage | not id. | rejected | failed | "
            "conf. wrong | err>0.1 | median s |")
    for gname, groups in summary.items():
        lines.append(f"### {gname}\n")
        lines.append(head.format(gname))
        lines.append("|" + "---|" * 13)
        for v, per in groups.items():
            for m in METHODS:
                st = per.get(m)
                if st is None:
                    continue
                cov = ("n/a" if m == "sindy" else
                       "n/a" if st["coverage"] is None else
                       f"{st['coverage']:.2f} ({st['covered']}/{st['with_interval']})")
                cw = "n/a" if st["confident_wrong"] is None else str(st["confident_wrong"])
                lines.append(f"| {v} | {m} | {st['n']} | {fmt(st['median'])} | {fmt(st['p90'])} | "
                             f"{fmt(st['worst'])} | {cov} | {st['not_identified']} | "
                             f"{st['rejected']} | {st['failed']} | {cw} | {st['err_gt_0.1']} | "
                             f"{fmt(st['median_seconds'], 's')} |")
        lines.append("")
    return "\n".join(lines)


def integrator_table(cases):
    lines = ["### RK4 substep check (data generated again with half the substep)\n",
             "| system | case | omega_max * substep | max abs diff | max diff / coordinate std | "
             "max diff / state max-norm |", "|---|---|---|---|---|---|"]
    for c in cases:
        ch = c.get("integrator_check")
        if ch:
            lines.append(f"| {c['system']} | {c['id']} | {ch['substep'] * c['omega_max']:.1e} | "
                         f"{ch['max_abs_diff']:.1e} | {ch['max_diff_over_coordinate_std']:.1e} | "
                         f"{ch['max_diff_over_state_max_norm']:.1e} |")
    return "\n".join(lines) + "\n"


def case_counts(cases):
    lines = ["### cases per stratum value\n"]
    for gname, key in groups_for(cases)[1:]:
        counts = {v: sum(1 for c in cases if key(c) == v) for v in group_values(gname, key, cases)}
        lines.append(f"- {gname}: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    return "\n".join(lines) + "\n"


def csympnet_result(c):
    r = c.get("methods", {}).get("csympnet")
    return None if r is None or r.get("status") == "skipped" else r


def verdict_of(r):
    return {"ok": "identified", "not_identified": "not identified",
            "rejected": "rejected"}.get(r.get("status"), "failed")


def check_names(cases):
    names = list(CHECK_NAMES)
    for c in cases:
        for ch in csympnet_result(c).get("checks") or []:
            if ch["name"] not in names:
                names.append(ch["name"])
    return names


def check_counts(cases, names):
    """per check name: (applicable, failed) over the cases' csympnet checks, and the number of
    cases with any failed check"""
    per = {nm: [0, 0] for nm in names}
    anyf = 0
    for c in cases:
        chs = csympnet_result(c).get("checks") or []
        for ch in chs:
            if ch["applicable"] is not False:
                per[ch["name"]][0] += 1
            if ch["passed"] is False:
                per[ch["name"]][1] += 1
        anyf += any(ch["passed"] is False for ch in chs)
    return per, anyf


def false_alarm_tables(cases):
    """valid cases: per check, failed / applicable and failed / all; overall, per sigma, shape"""
    cs = [c for c in cases if "violation" not in c["strata"] and csympnet_result(c)
          and csympnet_result(c).get("checks") is not None]
    if not cs:
        return ""
    names = check_names(cs)
    lines = ["### csympnet model checks on valid data: false alarms\n",
             "Per check: failed / applicable (rate), then failed / all cases of the row. "
             "'any': cases with at least one failed check / all.\n",
             "| stratum | value | n | " + " | ".join(names) + " | any |",
             "|" + "---|" * (len(names) + 4)]
    groups = [("all", lambda c: "all"), ("sigma", lambda c: f"{c['strata']['sigma']:g}"),
              ("shape", lambda c: c["strata"]["shape"])]
    for gname, key in groups:
        for v in group_values(gname, key, cs):
            sub = [c for c in cs if key(c) == v]
            per, anyf = check_counts(sub, names)
            n = len(sub)
            cells = []
            for nm in names:
                a, f = per[nm]
                rate = f"{f / a:.2f}" if a else "n/a"
                cells.append(f"{f}/{a} ({rate}); {f / n:.2f} of all")
            lines.append(f"| {gname} | {v} | {n} | " + " | ".join(cells)
                         + f" | {anyf}/{n} ({anyf / n:.2f}) |")
    return "\n".join(lines) + "\n"


def violation_tables(cases):
    """violation cases: per kind and size, detection rate of each check and of any check,
    verdict shares, confident answers whose interval misses the true / equivalent gamma"""
    cs = [c for c in cases if "violation" in c["strata"] and csympnet_result(c)]
    if not cs:
        return ""
    names = check_names(cs)
    lines = ["### csympnet model checks on violation data: detection\n",
             "Per check: cases where it failed / cases (applicable in brackets when fewer). "
             "Verdict shares over all cases of the row. 'conf. wrong': identified with an "
             "interval outside the true gamma (coulomb, quadratic drag: the equivalent total at "
             "A0; nonuniform: outside [min, max] of the modal rates; energy gain: the negative "
             "gamma).\n",
             "| violation | n | " + " | ".join(names)
             + " | any | rejected | not identified | identified | failed | conf. wrong |",
             "|" + "---|" * (len(names) + 8)]
    wrong = []
    key = lambda c: c["strata"]["violation"]  # noqa: E731
    for v in group_values("violation", key, cs):
        sub = [c for c in cs if key(c) == v]
        n = len(sub)
        per, anyf = check_counts(sub, names)
        cells = []
        for nm in names:
            a, f = per[nm]
            cells.append(f"{f / n:.2f} ({f}/{n}" + (f", appl. {a})" if a < n else ")"))
        verd = [verdict_of(csympnet_result(c)) for c in sub]
        shares = [f"{verd.count(x) / n:.2f}" for x in ("rejected", "not identified",
                                                        "identified")]
        cw = [c for c in sub if csympnet_result(c).get("confident_wrong")]
        wrong += cw
        lines.append(f"| {v} | {n} | " + " | ".join(cells) + f" | {anyf / n:.2f} ({anyf}/{n}) | "
                     + " | ".join(shares) + f" | {verd.count('failed')} | {len(cw)} |")
    lines.append("")
    if wrong:
        lines.append("Confident answers on violated data (identified, interval misses):\n")
        for c in wrong:
            r = csympnet_result(c)
            ref = c["violation"]["gamma_reference_range"]
            ref_s = f"{ref[0]:.3e}" if ref[0] == ref[1] else f"[{ref[0]:.3e}, {ref[1]:.3e}]"
            lines.append(f"- {c['id']} ({c['strata']['shape']}, sigma {c['strata']['sigma']:g}):"
                         f" gamma_hat {r['gamma_hat']:.3e}, interval [{r['ci_low']:.3e}, "
                         f"{r['ci_high']:.3e}], true {ref_s}")
    else:
        lines.append("No confident answer on violated data.")
    return "\n".join(lines) + "\n"


def core_choice(cases):
    """per method of CORE_CHOICE_METHODS and system ("all" first): cases run, cases whose
    report.json says choices.core.type == "library", other core types (counts), no report or
    no core given"""
    out = {}
    for m in CORE_CHOICE_METHODS:
        rs = [(c, c["methods"][m]) for c in cases
              if m in c.get("methods", {}) and c["methods"][m].get("status") != "skipped"]
        if not rs:
            continue
        per = {}
        key = lambda c: c["system"]  # noqa: E731
        for v in ["all"] + group_values("system", key, [c for c, _ in rs]):
            sub = [r for c, r in rs if v == "all" or c["system"] == v]
            types = [r.get("core_type") for r in sub]
            other = {}
            for t in types:
                if t is not None and t != "library":
                    other[t] = other.get(t, 0) + 1
            per[v] = {"n": len(sub), "library": types.count("library"), "other": other,
                      "unknown": types.count(None)}
        out[m] = per
    return out


def core_choice_table(choice):
    if not choice:
        return ""
    lines = ["### core chosen (report.json choices.core.type)\n",
             "csympnet: how often its own choice was the Hamiltonian-library core; "
             "csympnet_library: the core forced with --core library (a check that it was "
             "used). 'unknown': no report.json, or no core in it.\n",
             "| system | method | n | library | rate | other cores | unknown |",
             "|" + "---|" * 7]
    for m, per in choice.items():
        for v, st in per.items():
            other = ", ".join(f"{k} {x}" for k, x in sorted(st["other"].items())) or "-"
            rate = f"{st['library'] / st['n']:.2f}" if st["n"] else "n/a"
            lines.append(f"| {v} | {m} | {st['n']} | {st['library']} | {rate} | {other} | "
                         f"{st['unknown']} |")
    return "\n".join(lines) + "\n"


def verdict_tables(cases):
    """csympnet's verdict counts per stratum value"""
    cs = [c for c in cases if csympnet_result(c)]
    if not cs:
        return ""
    lines = ["### csympnet verdicts per stratum\n",
             "| stratum | value | n | " + " | ".join(VERDICTS) + " |", "|" + "---|" * 7]
    for gname, key in groups_for(cs):
        for v in group_values(gname, key, cs):
            verd = [verdict_of(csympnet_result(c)) for c in cs if key(c) == v]
            lines.append(f"| {gname} | {v} | {len(verd)} | "
                         + " | ".join(str(verd.count(x)) for x in VERDICTS) + " |")
    return "\n".join(lines) + "\n"


def clean_json(x):
    if isinstance(x, dict):
        return {str(k): clean_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [clean_json(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(float(x)) else None
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def write_outputs(args, meta, cases, interrupted=False):
    done = [c for c in cases if "methods" in c]
    summary = summarize(done)
    notes = (f"Notes: the oracle fits in natural units (it is given the true unit scales, q "
             f"offsets and time scale); sindy has no interval (coverage n/a) and no "
             f"'confident wrong'; error statistics are over the cases with a number "
             f"(not identified, rejected and failed cases are counted apart). sindy: local "
             f"cubic fit over {SG_WINDOW} samples, STLSQ threshold {STLSQ_THRESHOLD:g}, ridge "
             f"{STLSQ_RIDGE:g}. "
             f"The oracle's one-step least squares treats the noisy starting state of each step as "
             f"exact (errors in variables), so with noise it is biased and its interval can miss; "
             f"on noise-free data its residuals are integration error, not noise, so its "
             f"interval (width ~1e-9 relative) says nothing about coverage there.")
    if any("violation" in c["strata"] for c in done):
        notes += (" Violation cases: errors are relative to |gamma_reference| (the drawn gamma; "
                  "coulomb, quadratic drag: the equivalent total at A0; nonuniform: the mean "
                  "modal rate; energy gain: negative); 'confident wrong' there is any interval "
                  "outside gamma_reference_range (nonuniform: [min, max] modal rate), with no "
                  "error threshold.")
    choice = core_choice(done)
    checks = "\n".join(x for x in (false_alarm_tables(done), violation_tables(done),
                                    verdict_tables(done), core_choice_table(choice)) if x)
    body = "\n".join([case_counts(done), integrator_table(done), tables(summary)]
                     + ([checks] if checks else []))
    md = "\n".join([
        "# Identification benchmark" + (" (interrupted, partial)" if interrupted else ""), "",
        f"- command: `{meta['command']}`", f"- date: {meta['date']}",
        f"- uname -a: `{meta['uname']}`",
        f"- csympnet --version: {meta['csympnet_version']}",
        f"- cases: {len(done)} of {len(cases)} planned, seed {args.seed}", "", notes, "", body])
    res = dict(meta, interrupted=interrupted, summary=summary, core_choice=choice,
               cases=[dict(c) for c in cases if "methods" in c or "error" in c])
    with open(os.path.join(args.out, "results.json"), "w") as f:
        json.dump(clean_json(res), f, indent=1)
    with open(os.path.join(args.out, "summary.md"), "w") as f:
        f.write(md)
    return md, notes, body


def csympnet_version(exe):
    try:
        r = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=30)
        text = (r.stdout.strip() or r.stderr.strip()).splitlines()
        return text[0] if r.returncode == 0 and text else "n/a"
    except (OSError, subprocess.TimeoutExpired):
        return "n/a"


def uname():
    try:
        return subprocess.run(["uname", "-a"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return " ".join(platform.uname())


def progress(i, n, c):
    parts = []
    for m in METHODS:
        r = c["methods"].get(m)
        if r is None or r.get("status") == "skipped":
            continue
        if r.get("status") == "ok":
            parts.append(f"{m} {r['rel_err']:.1e}")
        elif r.get("status") == "rejected":
            parts.append(f"{m} rejected")
        else:
            parts.append(f"{m} {r.get('status')}")
    print(f"[{i}/{n}] {c['id']} d={c['d']} {c['strata']['ratio']} {c['strata']['units']} "
          f"{c['strata']['shape']} {c['strata']['steps']} sigma={c['strata']['sigma']:g}: "
          + ", ".join(parts), file=sys.stderr, flush=True)


def parse_args():
    """The parser (main reports its own checks through it) and the parsed options."""
    ap = argparse.ArgumentParser(
        description="Identification benchmark of the damping rate: csympnet fit against a "
                    "SINDy-style regression and a parametric oracle.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="See the top of this file for the systems, strata and peers.")
    ap.add_argument("--out", required=True, help="output directory")
    ap.add_argument("--cases", type=int, default=None,
                    help="number of cases (default 120, 8 with --quick; with --violations 60, "
                         "10 with --quick)")
    ap.add_argument("--violations", action="store_true",
                    help="run only violation cases (data that break one assumption)")
    ap.add_argument("--quick", action="store_true", help="a small subset of small cases")
    ap.add_argument("--seed", type=int, default=1, help="default 1")
    ap.add_argument("--only-peers", action="store_true",
                    help="skip csympnet (and csympnet_library)")
    ap.add_argument("--systems", default=None,
                    help="comma-separated subset of: " + ",".join(SYSTEM_NAMES)
                         + ', or "all" (default: all but ' + ",".join(EXTRA_SYSTEMS) + ")")
    ap.add_argument("--csympnet", default=os.path.join(REPO, "build", "bin", "csympnet"))
    ap.add_argument("--fit-args", default="",
                    help='extra options for every `csympnet fit`, e.g. --fit-args="--epochs 2000"')
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per fit (default 600)")
    ap.add_argument("--jobs", type=int, default=1, help="cases in parallel (default 1)")
    ap.add_argument("--momenta", choices=["given", "gradient", "savgol"], default="given",
                    help="p columns as generated (given, default), or computed from the noisy q "
                         "as a user without a momentum sensor would: numpy.gradient or a "
                         "Savitzky-Golay derivative (window 11, cubic)")
    ap.add_argument("--observed", action="store_true",
                    help="also fit every case from its positions alone (csympnet_positions) and "
                         "with p from centred differences of the noisy q "
                         "(csympnet_differenced), side by side with the given p")
    ap.add_argument("--library", action="store_true",
                    help="also fit every case with the Hamiltonian-library core forced "
                         "(`--core library`): method csympnet_library")
    ap.add_argument("--skip-peers", action="store_true",
                    help="skip the SINDy-style peer and the oracle (csympnet alone; "
                         "csympnet_library still runs with --library)")
    ap.add_argument("--force", action="store_true",
                    help="write into a non-empty --out (its cases/ folder is replaced)")
    return ap, ap.parse_args()


def main():
    ap, args = parse_args()
    if args.seed < 0:
        ap.error("--seed must be >= 0")
    if args.jobs < 1:
        ap.error("--jobs must be >= 1")
    if args.violations:
        n = args.cases if args.cases is not None else (10 if args.quick else 60)
    else:
        n = args.cases if args.cases is not None else (8 if args.quick else 120)
    if n < 1:
        ap.error("--cases must be >= 1")
    systems = DEFAULT_SYSTEMS
    if args.systems and args.systems.strip() == "all":
        systems = SYSTEM_NAMES
    elif args.systems:
        systems = [x.strip() for x in args.systems.split(",") if x.strip()]
        bad = [x for x in systems if x not in SYSTEM_NAMES]
        if bad or not systems:
            ap.error(f"unknown systems {bad}; choose from {','.join(SYSTEM_NAMES)}")
    try:
        extra = shlex.split(args.fit_args)
    except ValueError as e:
        ap.error(f"--fit-args: {e}")
    exe = os.path.abspath(args.csympnet)
    if not args.only_peers and not os.access(exe, os.X_OK):
        ap.error(f"no csympnet executable at {exe} (build it, give --csympnet, or --only-peers)")
    if os.path.isdir(args.out) and os.listdir(args.out) and not args.force:
        ap.error(f"{args.out} is not empty (give --force to reuse it)")
    args.out = os.path.abspath(args.out)
    os.makedirs(args.out, exist_ok=True)
    if os.path.isdir(os.path.join(args.out, "cases")):
        shutil.rmtree(os.path.join(args.out, "cases"))
    meta = {"command": shlex.join([sys.executable] + sys.argv),
            "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
            "uname": uname(),
            "csympnet": None if args.only_peers else exe,
            "csympnet_version": ("skipped (--only-peers)" if args.only_peers
                                 else csympnet_version(exe)),
            "seed": args.seed, "quick": args.quick, "violations": args.violations,
            "fit_args": extra, "timeout": args.timeout, "momenta": args.momenta,
            "observed": args.observed, "skip_peers": args.skip_peers, "library": args.library,
            "systems": list(systems),
            "settings": {"gen_omega_dt": GEN_OMEGA_DT, "oracle_omega_dt": ORACLE_OMEGA_DT,
                         "sg_window": SG_WINDOW, "sg_degree": SG_DEGREE,
                         "stlsq_threshold": STLSQ_THRESHOLD, "stlsq_ridge": STLSQ_RIDGE,
                         "library_cap": LIBRARY_CAP}}
    if args.violations:
        try:
            cases = plan_violations(n, args.seed, systems)
        except ValueError as e:
            ap.error(str(e))
    else:
        cases = plan(n, args.seed, systems)
    first = {}
    for c in cases:  # the integrator check: first case of each system (violation kind)
        first.setdefault(c["strata"]["violation"] if args.violations else c["system"],
                         c["index"])
    checked = set(first.values())

    got = {"signal": signal.SIGINT}

    def on_signal(signum, frame):
        got["signal"] = signum
        raise KeyboardInterrupt()
    # installed explicitly: a shell starts background jobs with SIGINT ignored
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    pool = cf.ThreadPoolExecutor(max_workers=args.jobs)
    futures = {pool.submit(run_case, c, args, c["index"] in checked, exe, extra): c for c in cases}
    pending = set(futures)
    done_count = 0
    try:
        while pending:
            finished, pending = cf.wait(pending, timeout=0.5, return_when=cf.FIRST_COMPLETED)
            for f in finished:
                c = futures[f]
                try:
                    f.result()
                except Interrupted:
                    continue
                except Exception as e:  # generation failed: a bug, report and keep going
                    c["error"] = f"{type(e).__name__}: {e}"
                    print(f"{c['id']}: {c['error']}", file=sys.stderr, flush=True)
                    continue
                done_count += 1
                progress(done_count, len(cases), c)
    except KeyboardInterrupt:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        STOP.set()
        with CHILDREN_LOCK:
            kids = list(CHILDREN)
        for p in kids:
            kill_group(p, signal.SIGTERM)
        deadline = time.monotonic() + 2.0
        for p in kids:
            try:
                p.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                kill_group(p, signal.SIGKILL)
        pool.shutdown(wait=False, cancel_futures=True)
        try:
            write_outputs(args, meta, cases, interrupted=True)
            print(f"interrupted; partial results in {args.out}", file=sys.stderr, flush=True)
        finally:
            os._exit(128 + int(got["signal"]))
    pool.shutdown()
    md, notes, body = write_outputs(args, meta, cases)
    print(notes + "\n")
    print(body)
    print(f"wrote {os.path.join(args.out, 'results.json')} and "
          f"{os.path.join(args.out, 'summary.md')}")
    errors = [c for c in cases if "error" in c]
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
