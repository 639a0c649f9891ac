"""Linear chains of unit masses between springs (fixed ends), one viscous rate gamma for every
mode: q'' = -K q - gamma q'. The positions in closed form, through the modes of K (any sample
times, any length), for the observed-records plan and its positions oracle."""
import math

import numpy as np


def chain_stiffness(springs):
    """K of d masses between d + 1 springs k_0..k_d (fixed ends)."""
    k = np.asarray(springs, dtype=float)
    d = k.size - 1
    K = np.zeros((d, d))
    for i in range(d):
        K[i, i] = k[i] + k[i + 1]
        if i + 1 < d:
            K[i, i + 1] = K[i + 1, i] = -k[i + 1]
    return K


def draw_springs(rng, d):
    """The springs of the carts of experiments/linked_positions_study.py: k_i = U(0.6, 1.4)
    (2 pi)^2, modes near 1 Hz."""
    return rng.uniform(0.6, 1.4, size=d + 1) * (2 * math.pi) ** 2


def modal_basis(K, gamma, t):
    """U (d, d) with K = U diag(w^2) U^T, and per mode the two free responses of
    a'' + gamma a' + w^2 a = 0 at times t: c(t) (a(0) = 1, a'(0) = 0) and s(t) (a(0) = 0,
    a'(0) = 1), each of shape (len(t), d). Over- or critically damped modes are handled through
    complex frequencies."""
    w2, U = np.linalg.eigh(K)
    wd = np.sqrt((w2 - 0.25 * gamma * gamma).astype(complex))
    wd = np.where(np.abs(wd) < 1e-300, 1e-300, wd)
    tt = np.asarray(t, dtype=float)[:, None]
    env = np.exp(-0.5 * gamma * tt)
    cos_ = np.cos(wd[None, :] * tt)
    sin_ = np.sin(wd[None, :] * tt) / wd[None, :]
    c = (env * (cos_ + 0.5 * gamma * sin_)).real
    s = (env * sin_).real
    return U, c, s


def positions(K, gamma, q0, v0, t):
    """q(t) of shape (len(t), d) from q(0) = q0, q'(0) = v0."""
    U, c, s = modal_basis(K, gamma, t)
    a0 = U.T @ np.asarray(q0, dtype=float)
    b0 = U.T @ np.asarray(v0, dtype=float)
    return (c * a0[None, :] + s * b0[None, :]) @ U.T


def velocities(K, gamma, q0, v0, t):
    """q'(t) of shape (len(t), d), in closed form: for each mode c' = -w^2 s and
    s' = exp(-gamma t / 2) (cos wd t - (gamma / 2) sin(wd t) / wd)."""
    w2, U = np.linalg.eigh(K)
    _, c, s = modal_basis(K, gamma, t)
    wd = np.sqrt((w2 - 0.25 * gamma * gamma).astype(complex))
    wd = np.where(np.abs(wd) < 1e-300, 1e-300, wd)
    tt = np.asarray(t, dtype=float)[:, None]
    ds = (np.exp(-0.5 * gamma * tt) * (np.cos(wd[None, :] * tt)
                                       - 0.5 * gamma * np.sin(wd[None, :] * tt) / wd[None, :])).real
    dc = -w2[None, :] * s
    a0 = U.T @ np.asarray(q0, dtype=float)
    b0 = U.T @ np.asarray(v0, dtype=float)
    return (dc * a0[None, :] + ds * b0[None, :]) @ U.T
