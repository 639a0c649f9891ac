"""The SINDy-style peer: sparse regression of dp/dt on a library of terms."""
import itertools
import math

import numpy as np

from ..common import check_stop

SG_WINDOW = 7            # samples in the local polynomial fit (sindy)
SG_DEGREE = 3
STLSQ_THRESHOLD = 1e-2
STLSQ_RIDGE = 1e-10
STLSQ_PASSES = 10
LIBRARY_CAP = 500

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
