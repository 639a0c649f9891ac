"""The observed-records plan (--observed-plan): records as they come from a camera, an encoder
or a long logger, each given to csympnet beside the oracle, the textbook fits and the
SINDy-style peer, in one run, with every method's CPU seconds.

Strata (the plan takes them in turn; a case's draws come from its own seed):

    linear-px         chains of 2-6 unit masses between springs (k_i = U(0.6, 1.4) (2 pi)^2),
                      one rate gamma = U(0.06, 0.2); positions only, in pixels (scale
                      U(50, 200), offset U(100, 500) per coordinate), 25 frames per second for
                      58 s with 3% of the frames dropped, noise 0.1-1% (log-uniform) of each
                      coordinate's spread; d cycles 2, 4, 6, 3, 5
    oversampled       chains of 1 or 2 masses, positions only in pixels, 30-1000 samples per
                      fastest period (log-uniform), 25 periods' worth of samples clamped to
                      3,000-10,000, regular steps; the amplitude falls 3-30 fold over the
                      record; noise 0.1-1%
    long-1e5          one mass, positions only in pixels, 10^5 samples at 50-200 samples per
                      period, the amplitude falling 5-50 fold; noise 0.1-1%
    encoder           a pendulum (V = -cos q) read by a 2048-count encoder: positions only, in
                      counts (rounded; an offset of 1,000-30,000 counts), no other noise;
                      amplitude 0.5-1.5 rad, 20-60 samples per small-amplitude period, 20-40
                      periods, the amplitude falling about 5-30 fold
    decay-into-noise  a pendulum with measured momenta, Gaussian noise 0.1-1% of the initial
                      amplitude (of q; of omega A0 for p), amplitude 0.3-1 rad, 30-100 samples
                      per period, 5,000-12,000 samples: the record lasts until the amplitude is
                      a third of the noise

(--quick: shorter records: linear-px 20 s, oversampled 1,000-2,000 samples, long 5,000, decay
1,500-2,500.) Methods:

    csympnet       `csympnet fit` on the file (positions only but for decay-into-noise); its
                   CPU seconds from wait4; the terms of report.json's "hamiltonian" (or the
                   core's type when the fit chose a neural core)
    oracle         the true form fitted to the whole record (peers/positions_oracle.py): of
                   positions; of positions and momenta for decay-into-noise, where the main
                   plan's one-step oracle (peers/oracle.py) also runs, as oracle_one_step
    textbook       damped sinusoids, one shared gamma and frequency per mode
                   (peers/textbook.py), started at the true modal frequencies (multi-dof; the
                   user's best case) or at the periodogram's peak (one mode), gamma at the
                   truth times exp(0.2 z)
    log_decrement  one-mode records: the decrement of the extremes (peers/textbook.py)
    sindy          the SINDy-style peer; on positions-only records its momenta are the
                   Savitzky-Golay derivative of the positions (window 11, cubic)
    csympnet_with_p  (--with-momenta; linear strata) `csympnet fit` on the same record with
                   measured momenta (p = q' in pixels per time unit, noise of the same share
                   of their spread): the cost of positions only as a CPU ratio, side by side

CPU seconds of the Python peers are process_time (exact with --jobs 1).
"""
import math
import os
import shutil
import time

import numpy as np

from . import linear
from .common import Interrupted, check_stop
from .generate import computed_momenta, log_uniform, write_csv
from .peers import positions_oracle, textbook
from .peers.csympnet import run_csympnet
from .peers.oracle import oracle as onestep_oracle
from .peers.sindy import sindy
from .runner import score
from .simulation import integrate
from .systems import make_system

OBSERVED_STRATA = ["linear-px", "oversampled", "long-1e5", "encoder", "decay-into-noise"]
LINEAR_STRATA = ["linear-px", "oversampled", "long-1e5"]
OBSERVED_METHODS = ["csympnet", "oracle", "textbook", "log_decrement", "sindy", "oracle_one_step",
                    "csympnet_with_p"]
LINEAR_PX_DOFS = [2, 4, 6, 3, 5]
ENCODER_COUNTS = 2048


def plan_observed(n, seed, strata):
    cases = []
    for i in range(n):
        st = strata[i % len(strata)]
        cases.append({"index": i, "id": f"o{i:03d}-{st}", "stratum": st, "within": i // len(strata),
                      "seed": [seed, 300000 + i], "strata": {"observed": st}})
    return cases


def _pixels(rng, q, sigma):
    """noise of sigma times each coordinate's spread, then a scale and an offset per coordinate"""
    d = q.shape[1]
    qn = q + sigma * q.std(axis=0)[None, :] * rng.normal(size=q.shape)
    scale = rng.uniform(50.0, 200.0, size=d)
    offset = rng.uniform(100.0, 500.0, size=d)
    return qn * scale + offset, scale, offset


def _linear_record(case, rng, quick):
    st = case["stratum"]
    if st == "linear-px":
        d = LINEAR_PX_DOFS[case["within"] % len(LINEAR_PX_DOFS)]
        k = linear.draw_springs(rng, d)
        gamma = float(rng.uniform(0.06, 0.2))
        t = np.arange(0.0, 20.0 if quick else 58.0, 1.0 / 25.0)
        keep = rng.uniform(size=t.size) >= 0.03
        keep[0] = keep[-1] = True
        t = t[keep]
        spp = 25.0 * 2 * math.pi / math.sqrt(np.linalg.eigvalsh(linear.chain_stiffness(k)).max())
    else:
        d = 1 if st == "long-1e5" else [1, 2][case["within"] % 2]
        k = linear.draw_springs(rng, d)
        K = linear.chain_stiffness(k)
        w2 = np.linalg.eigvalsh(K)
        if st == "oversampled":
            spp = log_uniform(rng, 30.0, 1000.0)
            n = int(min(2000 if quick else 10000, max(1000 if quick else 3000, 25 * spp)))
            fall = log_uniform(rng, 3.0, 30.0)
        else:
            spp = log_uniform(rng, 50.0, 200.0)
            n = 5000 if quick else 100000
            fall = log_uniform(rng, 5.0, 50.0)
        h = 2 * math.pi / math.sqrt(w2.max()) / spp
        t = h * np.arange(n)
        gamma = 2.0 * math.log(fall) / float(t[-1])
    K = linear.chain_stiffness(k)
    q0 = rng.normal(size=d)
    q = linear.positions(K, gamma, q0, np.zeros(d), t)
    sigma = log_uniform(rng, 1e-3, 1e-2)
    px, scale, offset = _pixels(rng, q, sigma)
    qnat = (px - offset[None, :]) / scale[None, :]
    w = np.sqrt(np.linalg.eigvalsh(K))
    # the same record with measured momenta (unit masses: p = q'), in pixels per time unit,
    # with noise of sigma times their spread (own generator: the positions are unchanged)
    v = linear.velocities(K, gamma, q0, np.zeros(d), t)
    vrng = np.random.default_rng(case["seed"] + [2])
    p_px = (v + sigma * v.std(axis=0)[None, :] * vrng.normal(size=v.shape)) * scale[None, :]
    return {"t": t, "q": px, "p": None, "p_measured": p_px, "q_natural": qnat, "gamma": gamma,
            "d": d,
            "springs": k.tolist(), "omegas": w.tolist(), "sigma": sigma,
            "samples_per_fastest_period": spp,
            "units": {"q_scale": scale.tolist(), "q_offset": offset.tolist(), "time_scale": 1.0}}


def _pendulum_record(case, rng, quick):
    st = case["stratum"]
    s = make_system("pendulum", rng, quick)
    spp = rng.uniform(20.0, 60.0) if st == "encoder" else rng.uniform(30.0, 100.0)
    h = 2 * math.pi / spp
    if st == "encoder":
        amp = rng.uniform(0.5, 1.5)
        n = int(rng.uniform(20.0, 40.0) * spp)
        gamma = 2.0 * math.log(log_uniform(rng, 5.0, 30.0)) / (n * h)
        sigma = 0.0
    else:
        amp = rng.uniform(0.3, 1.0)
        n = int(rng.uniform(1500, 2500) if quick else rng.uniform(5000, 12000))
        sigma = log_uniform(rng, 1e-3, 1e-2)
        gamma = 2.0 * math.log(3.0 / sigma) / (n * h)
    steps = np.full((1, n - 1), h)
    Q, P = integrate(s, gamma, np.array([[amp]]), np.array([[0.0]]), steps, 1e-3 / s["omega_max"])
    t = h * np.arange(n)
    q, p = Q[:, 0, :], P[:, 0, :]
    rec = {"t": t, "gamma": gamma, "d": 1, "amplitude": amp, "samples_per_fastest_period": spp,
           "system": s, "omegas": [1.0], "sigma": sigma}
    if st == "encoder":
        offset = int(rng.integers(1000, 30001))
        per = ENCODER_COUNTS / (2 * math.pi)
        counts = np.round(q * per) + offset
        rec.update(q=counts, p=None, q_natural=(counts - offset) / per,
                   units={"q_scale": [per], "q_offset": [float(offset)], "time_scale": 1.0,
                          "counts_per_revolution": ENCODER_COUNTS})
    else:
        qn = q + sigma * amp * rng.normal(size=q.shape)
        pn = p + sigma * amp * s["omega_max"] * rng.normal(size=p.shape)
        rec.update(q=qn, p=pn, q_natural=qn,
                   units={"q_scale": [1.0], "q_offset": [0.0], "time_scale": 1.0})
    return rec


def generate_observed(case, quick):
    rng = np.random.default_rng(case["seed"])
    if case["stratum"] in LINEAR_STRATA:
        return _linear_record(case, rng, quick)
    return _pendulum_record(case, rng, quick)


def _dominant_omega(t, q):
    x = q - q.mean()
    h = float(np.median(np.diff(t)))
    spec = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
    k = int(np.argmax(spec[1:])) + 1
    if 1 <= k < spec.size - 1:  # parabolic refinement on the log spectrum
        a, b, c = np.log(spec[k - 1:k + 2] + 1e-300)
        k = k + 0.5 * (a - c) / (a - 2 * b + c)
    return 2 * math.pi * k / (x.size * h)


def _timed(fn):
    """fn() -> dict (gamma_hat, ci_low, ci_high, extra); status, seconds, cpu_seconds added"""
    t0, c0 = time.monotonic(), time.process_time()
    try:
        r = fn()
        res = {"status": "ok" if math.isfinite(r["gamma_hat"]) else "failed", "identified": True,
               **r}
    except Interrupted:
        raise
    except Exception as e:  # a peer that breaks on a case is a failure of that peer
        res = {"status": "failed", "reason": f"{type(e).__name__}: {e}"}
    res["seconds"] = time.monotonic() - t0
    res["cpu_seconds"] = time.process_time() - c0
    return res


def _terms(res):
    """the csympnet terms, and whether any is a sin, cos or exp"""
    ham = res.get("hamiltonian")
    if isinstance(ham, dict) and isinstance(ham.get("terms"), list):
        names = [str(x.get("term")) for x in ham["terms"] if isinstance(x, dict)]
        res["terms"] = names
        res["sin_cos_exp"] = any(n.startswith(("sin", "cos", "exp")) for n in names)
    else:
        res["terms"] = None
        res["sin_cos_exp"] = None
    return res


def run_observed_case(case, args, exe, extra):
    check_stop()
    cdir = os.path.join(args.out, "cases", case["id"])
    os.makedirs(cdir, exist_ok=True)
    t0 = time.monotonic()
    rec = generate_observed(case, args.quick)
    d, t, gamma = rec["d"], rec["t"], rec["gamma"]
    case.update(d=d, gamma_true=gamma, samples=int(t.size), sigma=rec["sigma"],
                samples_per_fastest_period=rec["samples_per_fastest_period"],
                units=rec["units"], positions_only=rec["p"] is None,
                springs=rec.get("springs"), amplitude=rec.get("amplitude"),
                system="pendulum" if "system" in rec else "chain")
    case["generate_seconds"] = time.monotonic() - t0
    z = rec["q"] if rec["p"] is None else np.concatenate([rec["q"], rec["p"]], axis=1)
    data = os.path.join(cdir, "data.csv")
    write_csv(data, [(t, z)], d, positions_only=rec["p"] is None)
    case["paths"] = {"data": os.path.relpath(data, args.out)}
    rng = np.random.default_rng(case["seed"] + [1])
    g_start = gamma * math.exp(0.2 * float(np.clip(rng.standard_normal(), -2, 2)))
    methods = {}
    if rec["p"] is None and "system" not in rec:
        methods["oracle"] = _timed(lambda: positions_oracle.linear(
            t, rec["q_natural"], rec["springs"], g_start))
    elif rec["p"] is None:
        methods["oracle"] = _timed(lambda: positions_oracle.nonlinear(
            t, rec["q_natural"][:, 0], rec["system"], g_start))
    else:
        methods["oracle"] = _timed(lambda: positions_oracle.nonlinear(
            t, rec["q"][:, 0], rec["system"], g_start, p=rec["p"][:, 0]))
        info = {"d": 1, "omega_max": 1.0,
                "units": {"q_offset": [0.0], "s_q": 1.0, "s_p": 1.0, "time_scale": 1.0}}
        methods["oracle_one_step"] = _timed(
            lambda: onestep_oracle([(t, z)], info, rec["system"], rng))
    if d == 1:
        omegas = [_dominant_omega(t, rec["q"][:, 0])]
        methods["log_decrement"] = _timed(lambda: textbook.log_decrement(t, rec["q"][:, 0]))
    else:
        omegas = rec["omegas"]
    methods["textbook"] = _timed(lambda: textbook.damped_sinusoids(t, rec["q"], g_start, omegas))
    if rec["p"] is None:
        zs = computed_momenta([(t, np.concatenate([rec["q"], np.zeros_like(rec["q"])], axis=1))],
                              d, "savgol")
    else:
        zs = [(t, z)]
    methods["sindy"] = _timed(lambda: dict(zip(("gamma_hat", "extra"), sindy(zs, d)),
                                           ci_low=None, ci_high=None))
    if args.only_peers:
        methods["csympnet"] = {"status": "skipped"}
    else:
        outdir = os.path.join(cdir, "csympnet")
        if os.path.isdir(outdir):
            shutil.rmtree(outdir)
        case["paths"]["csympnet_out"] = os.path.relpath(outdir, args.out)
        methods["csympnet"] = _terms(run_csympnet(exe, data, outdir, extra, args.timeout,
                                                  cpu=True))
        if getattr(args, "with_momenta", False) and rec.get("p_measured") is not None:
            # the same record with measured momenta: the cost of positions only, side by side
            path = os.path.join(cdir, "data_with_p.csv")
            write_csv(path, [(t, np.concatenate([rec["q"], rec["p_measured"]], axis=1))], d)
            case["paths"]["data_with_p"] = os.path.relpath(path, args.out)
            outdir = os.path.join(cdir, "csympnet_with_p")
            if os.path.isdir(outdir):
                shutil.rmtree(outdir)
            methods["csympnet_with_p"] = _terms(run_csympnet(exe, path, outdir, extra,
                                                             args.timeout, cpu=True))
            cp, cq = methods["csympnet_with_p"].get("cpu_seconds"), \
                methods["csympnet"].get("cpu_seconds")
            if cp and cq is not None:
                methods["csympnet"]["cpu_over_with_p"] = cq / cp
    for m, r in methods.items():
        score(r, gamma)
    o = methods["oracle"]
    ow = (o["ci_high"] - o["ci_low"]) if o.get("status") == "ok" and o.get("ci_low") is not None \
        else None
    for m, r in methods.items():
        if m != "oracle" and ow and r.get("status") == "ok" and r.get("ci_low") is not None:
            r["width_over_oracle"] = (r["ci_high"] - r["ci_low"]) / ow
        oc = o.get("cpu_seconds")
        if m != "oracle" and oc and r.get("cpu_seconds") is not None:
            r["cpu_over_oracle"] = r["cpu_seconds"] / oc
    case["methods"] = {m: methods[m] for m in OBSERVED_METHODS if m in methods}
    return case
