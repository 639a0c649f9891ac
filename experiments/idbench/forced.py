"""Forced (driven) records: the systems, the inputs, the simulator and the records of the forced
plan (--forced-plan).

Model (unit masses, mass-normalised like the other systems of the benchmark):

    dq/dt = p,   dp/dt = -grad V(q) - gamma p + B u(t)

    duffing        d = 1, m = 1  V = k q^2/2 + b q^4/4, k = 1, b = 1 (hardening, the
                                 Silverbox's form), B = [1]
    pendulum       d = 1, m = 1  V = -k cos q, k = 1, B = [1]
    duffing-chain  d = 2, m = 1  two masses between fixed walls, three bonds, bond energy
                                 k_i x^2/2 + b_i x^4/4, k = (1, 0.6, 1.4), b = (1, 0.5, 0.8);
                                 the input on the first mass: B = [1, 0]^T (its structure, which
                                 entries are free, is known; their values are not)
    saturating     d = 1, m = 1  V = k q^2/2 + f l log cosh(q / l), k = 0.25, f = 0.15,
                                 l = 0.2 (a spring that saturates: stiffness 1 at rest, 0.25 far
                                 out; the force k q + f tanh(q / l) is outside csympnet's term
                                 library), B = [1]; only with --forced-systems

The input between samples is a first-order hold: u(t) is the straight line between the samples
u_k and u_{k+1} (the force B u(t) too); every record's u column is the input the system was
driven by, exactly. Integration: classical RK4 with a fixed substep, omega * substep <= 0.02,
with omega = omega_max sqrt(1 + 3 (2 A)^2) (the stiffest linear mode stiffened by a unit cubic
at twice the target amplitude A; the pendulum: omega_max); the records of one case are
integrated together, as columns.

Inputs (flat amplitude spectrum over the band [0.1 omega_min, 2.5 omega_max] of the linear
modes):

    multisine  a random-phase odd multisine: the odd harmonics k / (N h) of a period of N
               samples in the band, equal amplitudes, phases uniform in [0, 2 pi); scaled so that
               the linearised system's RMS response of q1 is the case's target amplitude A
               (duffing 0.3-0.5, pendulum 0.2-0.35 rad, chain 0.5-0.8, saturating 0.3-0.5, past
               the saturation at l = 0.2; log-uniform). Every
               multisine record is preceded by one unrecorded period (the transient; the record
               starts in the periodic steady state).
    rising     Gaussian noise filtered by a 4th-order Butterworth band-pass over the same band,
               normalised to the training input's RMS, times an envelope rising linearly from
               0 to 2 (the pendulum: 1.5, so that it does not go over the top; in the 10
               pendulum cases of seed 1 |q| stays below 1.3 rad): the input's
               RMS passes the training input's halfway (two thirds of the way for the
               pendulum), the extrapolation test. Starts at rest.

Records per case: train (a multisine, P periods), test-multisine (the same band and amplitude,
new phases, 2 periods) and test-rising (4096 samples; --quick: periods of 512 samples, P = 3,
rising 2048; else periods of 1024, P = 4). Positions only, with Gaussian noise of sigma times
each coordinate's RMS over the record, sigma log-uniform in [1e-3, 1e-2]; the input is
noise-free. gamma = r omega_max with r log-uniform in [0.03, 0.1];
samples per fastest linear period uniform in [20, 40]. Everything is drawn from the case's seed.

Sensitivity check: the two test records are integrated again with gamma (1 + 1e-4); when the
change of the free run (RMS over the outputs after the 100-sample warm-up, each output over its
noise standard deviation) exceeds 1 -- a model as close as the oracle's estimate (its relative
error is of the order of 1e-4) could not follow the record to within the noise -- the record
is marked ill_posed (info "sensitivity", "ill_posed"), and the tables leave it out of the RMS
medians and count it apart. The lightly damped hardening Duffing driven hard has coexisting
responses (7 of its 20 test records in the 30 cases of seed 1), less often the chain (4 of
20; the pendulum none).

CSV (the csympnet contract): header t,q1..qd,u1..um; u sampled at the same times as q.
"""
import math

import numpy as np

from .common import check_stop

FORCED_SYSTEMS = ["duffing", "pendulum", "duffing-chain"]
# systems run only when named (--forced-systems): outside the library of csympnet's terms
FORCED_EXTRA_SYSTEMS = ["saturating"]
FORCED_STRATA = ["multisine", "rising"]
TARGET_AMPLITUDE = {"duffing": (0.3, 0.5), "pendulum": (0.2, 0.35), "duffing-chain": (0.5, 0.8),
                    "saturating": (0.3, 0.5)}
SIZES = {False: {"period": 1024, "train_periods": 4, "test_periods": 2, "rising": 4096},
         True: {"period": 512, "train_periods": 3, "test_periods": 2, "rising": 2048}}
OMEGA_SUBSTEP = 0.02     # omega * RK4 substep when generating
GAMMA_RATIO = {"duffing": (0.03, 0.1), "pendulum": (0.03, 0.1), "duffing-chain": (0.03, 0.1),
               "saturating": (0.03, 0.1)}
SENSITIVITY_STEP = 1e-4  # the relative change of gamma of the sensitivity check
WARMUP_SAMPLES = 100     # the warm-up of the free-run score (peers/arx.py WARMUP)
RISING_PEAK = {"duffing": 2.0, "pendulum": 1.5, "duffing-chain": 2.0, "saturating": 2.0}


def _chain2_grad(q, th):
    """two masses, fixed ends, bonds x0 = q1, x1 = q2 - q1, x2 = -q2; th = k0, k1, k2, b0, b1, b2"""
    x = np.stack([q[0], q[1] - q[0], -q[1]])
    f = np.stack([th[i] * x[i] + th[3 + i] * x[i] ** 3 for i in range(3)])
    return np.stack([f[0] - f[1], f[1] - f[2]])


def forced_system(name):
    """dict: name, d, m, theta, theta_names, grad(q (d, c), theta) -> (d, c), B (d, m),
    b_free (list of (i, j) entries of B that are fitted), K (linear stiffness at q = 0),
    quartic (the coefficient of the amplitude correction of omega^2: 3/4 b A^2 for duffing)"""
    if name == "duffing":
        s = dict(d=1, m=1, theta=[1.0, 1.0], theta_names=["k", "b"],
                 grad=lambda q, th: th[0] * q + th[1] * q ** 3, B=np.array([[1.0]]))
        s["K"] = np.array([[1.0]])
    elif name == "pendulum":
        s = dict(d=1, m=1, theta=[1.0], theta_names=["k"],
                 grad=lambda q, th: th[0] * np.sin(q), B=np.array([[1.0]]))
        s["K"] = np.array([[1.0]])
    elif name == "duffing-chain":
        s = dict(d=2, m=1, theta=[1.0, 0.6, 1.4, 1.0, 0.5, 0.8],
                 theta_names=["k0", "k1", "k2", "b0", "b1", "b2"], grad=_chain2_grad,
                 B=np.array([[1.0], [0.0]]))
        s["K"] = np.array([[1.6, -0.6], [-0.6, 2.0]])
    elif name == "saturating":
        s = dict(d=1, m=1, theta=[0.25, 0.15, 0.2], theta_names=["k", "f", "l"],
                 grad=lambda q, th: th[0] * q + th[1] * np.tanh(q / th[2]), B=np.array([[1.0]]))
        s["K"] = np.array([[1.0]])
    else:
        raise ValueError(f"unknown forced system {name!r}")
    s["name"] = name
    s["b_free"] = [(i, j) for i in range(s["d"]) for j in range(s["m"]) if s["B"][i, j] != 0.0]
    w = np.sqrt(np.linalg.eigvalsh(s["K"]))
    s["omega_min"], s["omega_max"] = float(w.min()), float(w.max())
    return s


# ----------------------------------------------------------------------------------------------
# Simulation: RK4, first-order hold of the force between samples


def simulate(accel, q0, p0, force, h, substeps):
    """force: (n, d, c) the force B u at the n sample times (c columns: records or parameter
    sets); between samples the straight line (first-order hold). accel(q, p) -> (d, c) the
    unforced acceleration -grad V - gamma p. Returns Q, P of shape (n, d, c)."""
    n = force.shape[0]
    Q = np.empty((n,) + q0.shape)
    P = np.empty_like(Q)
    Q[0], P[0] = q0, p0
    q, p = q0, p0
    dt = h / substeps
    for k in range(n - 1):
        if k % 64 == 0:
            check_stop()
        f0, f1 = force[k], force[k + 1]
        df = (f1 - f0) / substeps
        for j in range(substeps):
            fa = f0 + j * df
            fm = fa + 0.5 * df
            fb = fa + df
            k1q, k1p = p, accel(q, p) + fa
            q2, p2 = q + 0.5 * dt * k1q, p + 0.5 * dt * k1p
            k2q, k2p = p2, accel(q2, p2) + fm
            q3, p3 = q + 0.5 * dt * k2q, p + 0.5 * dt * k2p
            k3q, k3p = p3, accel(q3, p3) + fm
            q4, p4 = q + dt * k3q, p + dt * k3p
            k4q, k4p = p4, accel(q4, p4) + fb
            q = q + dt / 6.0 * (k1q + 2.0 * (k2q + k3q) + k4q)
            p = p + dt / 6.0 * (k1p + 2.0 * (k2p + k3p) + k4p)
        Q[k + 1], P[k + 1] = q, p
    return Q, P


def system_accel(s, gamma, theta=None):
    th = s["theta"] if theta is None else theta
    return lambda q, p: -s["grad"](q, th) - gamma * p


# ----------------------------------------------------------------------------------------------
# Inputs


def band(s):
    return 0.1 * s["omega_min"], 2.5 * s["omega_max"]


def multisine(rng, N, h, lo, hi, periods):
    """unit-RMS random-phase odd multisine of period N samples over [lo, hi] (rad per time
    unit); `periods` periods, sampled at k h."""
    w0 = 2 * math.pi / (N * h)
    ks = np.arange(1, N // 2, 2)
    ks = ks[(ks * w0 >= lo) & (ks * w0 <= hi)]
    if ks.size == 0:
        raise ValueError("no harmonic in the band")
    ph = rng.uniform(0.0, 2 * math.pi, ks.size)
    t = h * np.arange(N * periods)
    u = np.cos(np.outer(t, ks * w0) + ph[None, :]).sum(axis=1)
    return u / math.sqrt(ks.size / 2.0), ks * w0


def linear_rms(s, gamma, omegas, amp):
    """RMS of q1 of the linearised system driven by sum_k amp cos(omega_k t) (per tone)"""
    d = s["d"]
    tot = 0.0
    for w in omegas:
        H = np.linalg.solve(s["K"] - w * w * np.eye(d) + 1j * w * gamma * np.eye(d), s["B"])
        tot += 0.5 * (amp * abs(H[0, 0])) ** 2
    return math.sqrt(tot)


def rising_noise(rng, n, h, lo, hi, rms, peak):
    """band-passed Gaussian noise of RMS `rms`, times an envelope rising linearly 0 -> peak"""
    from scipy.signal import butter, sosfilt
    nyq = math.pi / h
    sos = butter(4, [lo / nyq, min(hi / nyq, 0.95)], btype="bandpass", output="sos")
    x = sosfilt(sos, rng.standard_normal(n + 2000))[2000:]
    x = x / x.std() * rms
    return x * np.linspace(0.0, peak, n)


# ----------------------------------------------------------------------------------------------
# Records


def plan_forced(n, seed, systems):
    return [{"index": i, "id": f"f{i:03d}-{systems[i % len(systems)]}",
             "system": systems[i % len(systems)], "seed": [seed, 400000 + i]}
            for i in range(n)]


def generate_forced(case, quick):
    """the case's three records: dict name -> {t, q (noisy), q_clean, u}; and the case's info"""
    rng = np.random.default_rng(case["seed"])
    s = forced_system(case["system"])
    sz = SIZES[bool(quick)]
    N = sz["period"]
    r_lo, r_hi = GAMMA_RATIO[s["name"]]
    gamma = float(s["omega_max"] * math.exp(rng.uniform(math.log(r_lo), math.log(r_hi))))
    spp = float(rng.uniform(20.0, 40.0))
    h = 2 * math.pi / s["omega_max"] / spp
    lo, hi = band(s)
    a_lo, a_hi = TARGET_AMPLITUDE[s["name"]]
    target = float(math.exp(rng.uniform(math.log(a_lo), math.log(a_hi))))
    sigma = float(math.exp(rng.uniform(math.log(1e-3), math.log(1e-2))))
    u_tr, omegas = multisine(rng, N, h, lo, hi, 1 + sz["train_periods"])
    u_rms = target / linear_rms(s, gamma, omegas, math.sqrt(2.0 / omegas.size))
    u_tr = u_rms * u_tr
    u_ms = u_rms * multisine(rng, N, h, lo, hi, 1 + sz["test_periods"])[0]
    u_ri = rising_noise(rng, sz["rising"], h, lo, hi, u_rms, RISING_PEAK[s["name"]])
    # the three records as three columns of one integration (zero input past a record's end),
    # and the two test records again with gamma (1 + SENSITIVITY_STEP): the sensitivity check
    n_max = max(u_tr.size, u_ms.size, u_ri.size)
    U = np.zeros((n_max, s["m"], 5))
    for c, u in enumerate((u_tr, u_ms, u_ri, u_ms, u_ri)):
        U[:u.size, 0, c] = u
    force = np.einsum("dm,nmc->ndc", s["B"], U)
    # substep: the stiffest linear mode, stiffened by the hardening at twice the target
    w_top = s["omega_max"] * math.sqrt(1.0 + 3.0 * (2.0 * target) ** 2) \
        if s["name"] != "pendulum" else s["omega_max"]
    substeps = max(1, int(math.ceil(h * w_top / OMEGA_SUBSTEP)))
    z = np.zeros((s["d"], 5))
    gammas = gamma * np.array([1.0, 1.0, 1.0, 1.0 + SENSITIVITY_STEP, 1.0 + SENSITIVITY_STEP])
    Q, _ = simulate(system_accel(s, gammas), z, z, force, h, substeps)
    records = {}
    for c, (name, u, skip) in enumerate((("train", u_tr, N), ("test-multisine", u_ms, N),
                                         ("test-rising", u_ri, 0))):
        q = Q[skip:u.size, :, c]
        noise = sigma * q.std(axis=0)[None, :] * rng.standard_normal(q.shape)
        records[name] = {"t": h * np.arange(q.shape[0]), "q": q + noise, "q_clean": q,
                         "u": u[skip:, None]}
    sens = {}
    for c, name in ((3, "test-multisine"), (4, "test-rising")):
        q = records[name]["q_clean"]
        skip = N if name == "test-multisine" else 0
        dq = Q[skip:skip + q.shape[0], :, c] - q
        noise = sigma * q.std(axis=0)
        sens[name] = float(np.sqrt(np.mean(np.square(dq[WARMUP_SAMPLES:]).mean(axis=0)
                                           / np.square(noise))))
    qmax = np.abs(records["train"]["q_clean"]).max(axis=0)
    beyond = float((np.abs(records["test-rising"]["q_clean"]) > qmax[None, :]).any(axis=1).mean())
    info = {"d": s["d"], "m": s["m"], "gamma_true": gamma, "h": h,
            "samples_per_fastest_period": spp, "sigma": sigma, "target_amplitude": target,
            "u_rms": float(u_rms), "band": [lo, hi], "tones": int(omegas.size),
            "substeps": substeps, "theta_true": list(s["theta"]), "B_true": s["B"].tolist(),
            "rising_share_beyond_train": beyond, "sensitivity": sens,
            "ill_posed": {k: v > 1.0 for k, v in sens.items()},
            "q_rms": {k: r["q_clean"].std(axis=0).tolist() for k, r in records.items()},
            "samples": {k: int(r["t"].size) for k, r in records.items()}}
    return records, info, s


def write_forced_csv(path, t, q, u):
    d, m = q.shape[1], u.shape[1]
    head = ["t"] + [f"q{i + 1}" for i in range(d)] + [f"u{j + 1}" for j in range(m)]
    with open(path, "w") as f:
        f.write(",".join(head) + "\n")
        for k in range(t.size):
            f.write(",".join(repr(float(x)) for x in (t[k], *q[k], *u[k])) + "\n")
