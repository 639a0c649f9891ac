"""The case plans (balanced strata) and the generation of a case's data: parameters, RK4,
units, noise; momenta computed from positions; the CSV writer."""
import itertools
import math

import numpy as np

from .common import (GEN_OMEGA_DT, RATIO_DECADE, RATIO_STRATA, SHAPE_STRATA, SIGMA_STRATA,
                     STEPS_STRATA, UNITS_STRATA, VIOLATION_STRATA)
from .simulation import integrate
from .systems import make_system
from .violations import VIOLATION_SYSTEMS, violation_family, violation_record, violation_setup

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
