"""The fits a user would write for a record of positions, with no model of the forces:

    damped_sinusoids  least squares of q_i(t) = c_i + sum_k exp(-gamma t / 2) (a_ik cos w_k t
                      + b_ik sin w_k t) over all coordinates at once, one gamma and one
                      frequency per mode shared by the coordinates, each coordinate weighted by
                      its own residual spread (experiments/linked_positions_study.py's textbook,
                      reused as it is), in the file's units; interval: estimate +- 1.96 standard
                      errors (Gauss-Newton covariance scaled by the residual variance).
    log_decrement     one mode: the half peak-to-peak amplitudes A_j between consecutive
                      extremes (scipy.signal.find_peaks, at least 0.6 of the dominant period of
                      the periodogram apart), log A_j = a - (gamma / 2) t_j by least squares
                      over the extremes whose amplitude is above 20 times the noise (estimated
                      from the second differences); interval: +- t_{n-2} standard errors of the
                      slope. The rate of the energy is gamma, that of the amplitude gamma / 2.
"""
import math
import os
import sys

import numpy as np

from ..common import REPO


def damped_sinusoids(t, q, start_gamma, start_omegas, level=0.95):
    """t (n,), q (n, d) in the file's units; start_omegas: the undamped frequencies of the modes
    (the user's best case: known), start_gamma: gamma's start. Returns gamma_hat, ci_low,
    ci_high and extras."""
    try:
        from linked_positions_study import textbook
    except ImportError:  # the package imported from elsewhere: the study lives beside it
        sys.path.insert(0, os.path.join(REPO, "experiments"))
        from linked_positions_study import textbook
    q = np.asarray(q, dtype=float)
    case = {"t": np.asarray(t, dtype=float), "q": q, "d": q.shape[1],
            "omegas": np.asarray(start_omegas, dtype=float), "gamma": float(start_gamma)}
    r = textbook(case, level)
    return {"gamma_hat": r["gamma"], "ci_low": r["low"], "ci_high": r["high"],
            "extra": {"start_gamma": float(start_gamma), "modes": int(len(start_omegas))}}


def _noise_sd(q):
    """Gaussian noise std from second differences (var 6 sigma^2), robust (median)."""
    d2 = np.diff(q, 2)
    return float(np.median(np.abs(d2 - np.median(d2))) / 0.6745 / math.sqrt(6.0))


def log_decrement(t, q, level=0.95, min_snr=20.0):
    """t (n,), q (n,) of one mode. Returns gamma_hat, ci_low, ci_high and extras."""
    from scipy.signal import find_peaks
    from scipy.stats import t as student
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    x = q - np.mean(q)
    h = float(np.median(np.diff(t)))
    # dominant period from the periodogram (a regular grid's FFT; gaps are few here)
    spec = np.abs(np.fft.rfft(x * np.hanning(x.size))) ** 2
    freqs = np.fft.rfftfreq(x.size, h)
    k = int(np.argmax(spec[1:])) + 1
    period = 1.0 / freqs[k]
    dist = max(1, int(0.6 * period / h))
    hi = find_peaks(x, distance=dist)[0]
    lo = find_peaks(-x, distance=dist)[0]
    ext = sorted([(i, 1) for i in hi] + [(i, -1) for i in lo])
    amps, times = [], []
    for (i, si), (j, sj) in zip(ext[:-1], ext[1:]):
        if si != sj:
            amps.append(0.5 * abs(q[i] - q[j]))
            times.append(0.5 * (t[i] + t[j]))
    amps = np.asarray(amps)
    times = np.asarray(times)
    noise = _noise_sd(q)
    keep = amps > min_snr * noise
    # the decay stops where the amplitude reaches the noise: only the extremes before the first
    # one below the threshold
    if keep.size and not keep.all():
        keep[int(np.argmin(keep)):] = False
    n = int(keep.sum())
    if n < 4:
        raise RuntimeError(f"log decrement: {n} extremes above {min_snr:g} times the noise")
    X = np.column_stack([np.ones(n), times[keep]])
    y = np.log(amps[keep])
    coef, res, _, _ = np.linalg.lstsq(X, y, rcond=None)
    r = y - X @ coef
    s2 = float(r @ r) / max(1, n - 2)
    cov = s2 * np.linalg.inv(X.T @ X)
    se = 2.0 * math.sqrt(max(cov[1, 1], 0.0))
    g = -2.0 * float(coef[1])
    tq = float(student.ppf(0.5 + level / 2, max(1, n - 2)))
    return {"gamma_hat": g, "ci_low": g - tq * se, "ci_high": g + tq * se,
            "extra": {"extremes": n, "extremes_found": int(len(amps)), "noise_sd": noise,
                      "period": period}}
