"""The array forms a user may hand over for trajectories, as one list of (t, z) pairs.

One module, imported by the estimator, `identify`, `fit_trajectories` and `Model.score`, so
that every front end reads the same forms the same way (and none imports another for them).
"""

import numpy as np

from . import _checks

# What a record holds: whole states (q and p) or positions alone.
OBSERVED = ("states", "positions")


def padded_positions(z):
    """Positions (M, d), (M,), (K, M, d) or a list of them, each with d columns of zeros
    appended: the state arrays the trajectory checks read (the zeros are never used)."""
    def pad(a):
        a = np.asarray(a)
        if a.ndim == 1:
            a = a.reshape(-1, 1)
        return np.concatenate([a, np.zeros_like(a, dtype=float)], axis=-1)
    if isinstance(z, (list, tuple)):
        return [pad(a) for a in z]
    return pad(z) if np.ndim(z) != 3 else np.concatenate(
        [np.asarray(z), np.zeros(np.shape(z))], axis=-1)


def split_by_label(t, z, traj):
    """Rows of (t, z) grouped by a label column whose runs must be contiguous (as the CSV)."""
    labels = np.asarray(traj)
    if labels.ndim != 1 or labels.shape[0] != z.shape[0]:
        raise ValueError(f"traj: expected one label per row ({z.shape[0]}), got shape {labels.shape}")
    starts = np.flatnonzero(np.r_[True, labels[1:] != labels[:-1]])
    ends = np.r_[starts[1:], labels.shape[0]]
    seen = set()
    out = []
    for s, e in zip(starts, ends):
        key = labels[s].item()
        if key in seen:
            raise ValueError(
                f"traj: the rows of trajectory {key!r} are not contiguous (it reappears at row "
                f"{s}); expected each trajectory's rows together"
            )
        seen.add(key)
        out.append((t[s:e], z[s:e]))
    return out


def as_trajectories(t, z, traj):
    """The accepted trajectory forms (see fit_trajectories) as a list of (t, z) pairs."""
    if isinstance(t, (list, tuple)) and isinstance(z, (list, tuple)):
        if traj is not None:
            raise ValueError("traj: not used when t and z are lists of trajectories")
        if len(t) != len(z):
            raise ValueError(f"t, z: {len(t)} time arrays but {len(z)} state arrays")
        return list(zip(t, z))
    elif np.ndim(z) == 3:
        if traj is not None:
            raise ValueError("traj: not used when z holds K trajectories as (K, M, 2d)")
        za = np.asarray(z)
        ta = np.broadcast_to(np.asarray(t), za.shape[:2]) if np.ndim(t) == 1 else np.asarray(t)
        if ta.shape != za.shape[:2]:
            raise ValueError(f"t: expected shape (M,) or {za.shape[:2]} for z of shape {za.shape}")
        return list(zip(ta, za))
    else:
        zs, _ = _checks.states("z", z, allow_single=False)
        ts = _checks.vector("t", t, length=zs.shape[0])
        return [(ts, zs)] if traj is None else split_by_label(ts, zs, traj)
