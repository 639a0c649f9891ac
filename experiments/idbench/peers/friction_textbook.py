"""The fit a user writes for a free decay with friction: the envelope, not the motion.

    envelope   the extremes of q about its rest position (the centre that the upper and lower
               envelopes mirror each other about: rest_position), found per trajectory as the largest |q - rest| between sign changes of
               q - rest and refined by a parabola through the five samples around each, above
               twenty times the noise (second differences); consecutive extremes' magnitudes
               (A_n, A_n+1) of a trajectory regressed by least squares on the form of the
               record's dissipation, exact for a linear oscillator over a half cycle T/2:
                   viscous   A_n+1 = a A_n
                   coulomb   A_n+1 = a A_n - b           ("viscous plus a constant loss")
                   drag      A_n+1 = a A_n - b A_n^2     (b = 4c/3 for small damping)
               with a = exp(-gamma T/4), T/2 the median time between extremes, so that
               gamma = -4 ln(a) / T, mu = b omega^2 / (1 + a) (omega^2 = (2 pi / T)^2 +
               gamma^2 / 4) and c = 3 b / 4; interval: +- t_(n-k) standard errors of the
               regression, carried to gamma and the rate by their derivatives (delta method).

It knows the kind of dissipation (the user's best case), not the potential: a pendulum's
amplitude-dependent period is read as one T.
"""
import math

import numpy as np


def _noise_sd(q):
    d2 = np.diff(q, 2)
    return float(np.median(np.abs(d2 - np.median(d2))) / 0.6745 / math.sqrt(6.0))


def extremes(t, x, floor, signed=False):
    """(times, |x| at the extremes) between sign changes of x, each refined by a parabola
    through five samples around the largest |x| of its half cycle; those above floor (signed:
    also each extreme's sign)."""
    sign = np.sign(x)
    cuts = np.flatnonzero(np.diff(sign) != 0) + 1
    bounds = np.concatenate([[0], cuts, [x.size]])
    ts, amps, signs = [], [], []
    for a, b in zip(bounds[:-1], bounds[1:]):
        if b - a < 5 or a == 0 or b == x.size:  # a cut-off half cycle at either end
            continue
        k = a + int(np.argmax(np.abs(x[a:b])))
        lo, hi = max(k - 2, 0), min(k + 3, x.size)
        tt, xx = t[lo:hi] - t[k], x[lo:hi]
        if tt.size >= 3:
            c = np.polyfit(tt, xx, 2)
            tv = -c[1] / (2 * c[0]) if c[0] != 0 else 0.0
            if abs(tv) <= (t[hi - 1] - t[lo]):
                amp, tk = abs(np.polyval(c, tv)), t[k] + tv
            else:
                amp, tk = abs(x[k]), t[k]
        else:
            amp, tk = abs(x[k]), t[k]
        if amp > floor:
            ts.append(tk)
            amps.append(amp)
            signs.append(1.0 if x[k] > 0 else -1.0)
    if signed:
        return np.array(ts), np.array(amps), np.array(signs)
    return np.array(ts), np.array(amps)


def rest_position(t, q, rounds=3):
    """The centre the motion decays about: the upper and lower envelopes are mirror images
    about it (for viscous damping, dry friction and drag alike), so each extreme and the mean
    of its two neighbours, which lie on the other envelope, straddle it; the median of their
    midpoints, started from the mean of q and refined with the extremes it gives."""
    rest = float(np.mean(q))
    for _ in range(rounds):
        ts, amps, signs = extremes(t, q - rest, 0.0, signed=True)
        if amps.size < 3:
            break
        x = rest + signs * amps
        mids = 0.5 * (x[1:-1] + 0.5 * (x[:-2] + x[2:]))
        rest = float(np.median(mids))
    return rest


def envelope_fit(rec, kind, level=0.95):
    from scipy.stats import t as student
    pairs, halves, rests = [], [], []
    for j in np.unique(rec["traj"]):
        sel = rec["traj"] == j
        t, q = rec["t"][sel], rec["q"][sel]
        rest = rest_position(t, q)
        rests.append(rest)
        noise = _noise_sd(q)
        ts, amps = extremes(t, q - rest, 20.0 * max(noise, 1e-12))
        for n in range(amps.size - 1):
            pairs.append((amps[n], amps[n + 1]))
            halves.append(ts[n + 1] - ts[n])
    if len(pairs) < 4:
        return {"status": "failed", "reason": f"{len(pairs)} pairs of extremes"}
    a_n, a_next = np.array(pairs).T
    half = float(np.median(halves))
    period = 2 * half
    cols = {"viscous": [a_n], "coulomb": [a_n, -np.ones_like(a_n)],
            "pendulum-coulomb": [a_n, -np.ones_like(a_n)], "drag": [a_n, -a_n ** 2]}[kind]
    x = np.column_stack(cols)
    coef, *_ = np.linalg.lstsq(x, a_next, rcond=None)
    r = a_next - x @ coef
    dof = a_n.size - x.shape[1]
    if dof < 2:
        return {"status": "failed", "reason": "too few extremes for the form"}
    cov = float(r @ r) / dof * np.linalg.inv(x.T @ x)
    tq = float(student.ppf(0.5 + level / 2, dof))
    a = float(coef[0])
    if not 0 < a < 1:
        return {"status": "failed", "reason": f"the decrement a = {a:.4g} is not in (0, 1)"}
    gamma = -4.0 * math.log(a) / period
    g_se = 4.0 / (a * period) * math.sqrt(cov[0, 0])
    res = {"gamma_hat": gamma, "ci_low": gamma - tq * g_se, "ci_high": gamma + tq * g_se,
           "extra": {"pairs": int(a_n.size), "period": period, "rest": rests}}
    if kind != "viscous":
        b = float(coef[1])
        w2 = (2 * math.pi / period) ** 2 + 0.25 * gamma * gamma
        if kind == "drag":
            val, grad = 0.75 * b, np.array([0.0, 0.75])
        else:
            val = b * w2 / (1 + a)
            grad = np.array([-b * w2 / (1 + a) ** 2, w2 / (1 + a)])
        se = math.sqrt(max(float(grad @ cov @ grad), 0.0))
        res["rate"] = {"kind": "drag" if kind == "drag" else "coulomb", "value": val,
                       "low": val - tq * se, "high": val + tq * se}
    return res
