"""The user's records, read once: every form of data the package takes is converted here, at
the entry that receives it, into the trajectories the library takes, and the result is handed
on; no module after the entry reads the user's arrays again.

The forms:
  - states (M, 2d), each row q1..qd then p1..pd, or positions alone (M, d), (M,) for d = 1
    (observed="positions"). Positions travel as positions, d columns: the library is told
    which it gets (`_core.identify(..., positions_only)`, `_core.Model.score_positions`);
  - times t (M,), strictly increasing; the estimator also takes one step, or none;
  - one trajectory; rows labelled by trajectory (traj; each label's rows together); K
    trajectories as (K, M, ·) with t (M,) or (K, M); lists of arrays, one per trajectory;
  - independent pairs (z0, z1, h): identify fits each pair as a trajectory of two samples at
    the times (0, h);
  - a pandas DataFrame or Series, read by its column names (_frames.py);
  - known inputs u: (M,) or (M, m) per trajectory, sampled at its times.

What comes out is a list of `Trajectory(t, z)` of float64 C-order arrays (what the binding's
`trajectories_from` reads, with one copy into the library's column-major matrices), or
`Records`: those trajectories with what identify needs besides them.

A refusal raises TypeError (the wrong kind of object) or ValueError (a wrong shape or value),
names the argument as the caller spelled it (z, x, t[1], trajectories[0] z, u[0], ...) and says
what was expected.
"""

import warnings
from collections import namedtuple

import numpy as np

from . import _checks, _core, _frames

# What a record holds: whole states (q and p) or positions alone.
OBSERVED = ("states", "positions")
# The clock's units (identify/time_unit.hpp).
TIME_UNITS = tuple(_core.time_units())

Pairs = namedtuple("Pairs", "z0 z1 h")
Pairs.__doc__ = """Snapshot pairs: z0, z1 of shape (N, 2d) (rows are states, q1..qd then
p1..pd) and steps h of shape (N,), with z1 ≈ Φ_h(z0)."""

Trajectory = namedtuple("Trajectory", "t z")
Trajectory.__doc__ = """One trajectory: times t of shape (n+1,), states z of shape (n+1, 2d)."""


class LayoutWarning(UserWarning):
    """Warned by `identify` and `CSympNetID.fit` when `observed` is not given and the columns
    of an array are read as whole states, q1..qd then p1..pd: two columns are then one
    coordinate and its momentum (d = 1), not two positions. Pass observed="positions" when
    the columns are positions alone (a camera, an encoder), or observed="states" to say that
    they are states and silence this. A pandas DataFrame says which by its column names
    (q1..qd with p1..pd: states; any other names: positions), so it is not warned about."""


class NoTimesWarning(UserWarning):
    """Warned by CSympNetID.fit when neither times nor t_default are given: the samples are
    then taken one time unit apart, so gamma_ is a rate per sample, not per second (or
    whatever unit your clock has). Pass t (times or one step) or t_default to fit."""


class Records:
    """Trajectories read at an entry, with what identify needs besides them.

    trajectories  list of Trajectory: t (M,), z (M, 2d) states or (M, d) positions
    observed      "states" or "positions"
    pairs         True when each trajectory is an independent pair (times 0 and h)
    inputs        None, or one (M, m) array of known inputs per trajectory
    time_unit     the clock's unit, or None when unknown; unit_source says where it was read
                  ("time_unit", or "column 't_ms'")
    """

    def __init__(self, trajectories, observed="states", pairs=False, inputs=None,
                 time_unit=None, unit_source="time_unit"):
        self.trajectories = trajectories
        self.observed = observed
        self.pairs = pairs
        self.inputs = inputs
        self.time_unit = time_unit
        self.unit_source = unit_source

    @property
    def positions_only(self):
        return self.observed == "positions"

    def steps(self):
        """Every step between consecutive samples, trajectory after trajectory (for pairs:
        their h, since 0 + h − 0 is h exactly)."""
        return np.concatenate([np.diff(tr.t) for tr in self.trajectories])


# --- one array ---------------------------------------------------------------------------

def positions(name, q, dim=None):
    """Positions (M, d), or (M,) for d = 1 → (M, d) float64, finite."""
    a = _checks.real_array(name, q)
    if a.ndim == 1:
        a = a.reshape(-1, 1)
    if a.ndim != 2 or a.shape[1] == 0:
        raise ValueError(f"{name}: expected positions (M, d), or (M,) for d = 1, got an array "
                         f"of shape {np.shape(q)}")
    if dim is not None and a.shape[1] != dim:
        raise ValueError(f"{name}: positions have {a.shape[1]} columns, expected d = {dim} "
                         "(q1..qd)")
    _checks.require_finite(name, a)
    return a


def _samples(name, z, observed, dim=None):
    if observed == "positions":
        return positions(name, z, dim)
    return _checks.states(name, z, dim=dim, allow_single=False)[0]


# Like the CLI's readers: a state beyond this in magnitude has a square that overflows double,
# so no loss on it is finite and training would keep its starting point.
MAX_TRAINING_MAGNITUDE = 1e150


def trainable(name, a):
    """Refuses training data with a value whose square overflows (as `csympnet fit` does)."""
    big = np.abs(a) > MAX_TRAINING_MAGNITUDE
    if np.any(big):
        at = tuple(int(i) for i in np.argwhere(big)[0])
        raise ValueError(
            f"{name}: {a[at]!r} at index {at} is too large to train on (its square overflows "
            f"double); expected |value| <= {MAX_TRAINING_MAGNITUDE:g}")
    return a


# --- trajectories and pairs --------------------------------------------------------------

def trajectory(name, t, z, observed="states", dim=None):
    """One trajectory: times (M,) strictly increasing, states (M, 2d) or positions (M, d);
    `dim` the columns expected (2d or d), or None."""
    za = _samples(f"{name} z", z, observed, dim)
    ta = _checks.vector(f"{name} t", t, length=za.shape[0], min_length=1)
    if ta.shape[0] > 1 and not np.all(np.diff(ta) > 0):
        k = int(np.argmax(np.diff(ta) <= 0))
        raise ValueError(
            f"{name} t: expected strictly increasing times, but t[{k + 1}] = {ta[k + 1]!r} "
            f"follows t[{k}] = {ta[k]!r}"
        )
    return Trajectory(ta, za)


def trajectory_list(trajs, name="trajectories", dim=None, observed="states"):
    """Checked list of Trajectory from a Trajectory, a (t, z) pair or a list of them."""
    if isinstance(trajs, Trajectory) or (
        isinstance(trajs, tuple) and len(trajs) == 2 and np.ndim(trajs[0]) == 1
        and np.ndim(trajs[1]) == 2
    ):
        trajs = [trajs]
    if not isinstance(trajs, (list, tuple)) or not trajs:
        raise TypeError(f"{name}: expected a non-empty list of (t, z) trajectories")
    out = []
    for k, item in enumerate(trajs):
        if not isinstance(item, (tuple, list)) or len(item) != 2:
            raise TypeError(f"{name}[{k}]: expected a (t, z) pair")
        out.append(trajectory(f"{name}[{k}]", item[0], item[1], observed, dim))
    return out


def same_dimension(name, arrays, observed="states"):
    """A list of trajectories' arrays, (M, d) positions (or (M,): d = 1) or (M, 2d) states:
    each must have the first's d, refused naming the entry and both dimensions (the library
    would say only that the trajectories differ). Entries that are no 1-D or 2-D array are
    left to the shape checks that follow."""
    def columns(a):
        n = np.ndim(a)
        return 1 if n == 1 else np.shape(a)[1] if n == 2 else None
    if not isinstance(arrays, (list, tuple)) or not arrays:
        return
    first = columns(arrays[0])
    by_positions = observed == "positions"
    kind = "position" if by_positions else "state"
    for k, a in enumerate(arrays[1:], start=1):
        c = columns(a)
        if first is None or c is None or c == first:
            continue
        d0, dk = (first, c) if by_positions else (first / 2, c / 2)
        raise ValueError(f"{name}[{k}]: {c} {kind} columns (d = {dk:g}), but {name}[0] has "
                         f"{first} (d = {d0:g}); expected every trajectory of the list to "
                         f"have the same d")


def _split_by_label(t, z, traj):
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


def _split(t, z, traj, observed):
    """The trajectory forms of (z, t, traj) as a list of (t, z) pairs, each still to check."""
    if isinstance(t, (list, tuple)) and isinstance(z, (list, tuple)):
        if traj is not None:
            raise ValueError("traj: not used when t and z are lists of trajectories")
        if len(t) != len(z):
            raise ValueError(f"t, z: {len(t)} time arrays but {len(z)} state arrays")
        return list(zip(t, z))
    if np.ndim(z) == 3:
        if traj is not None:
            raise ValueError("traj: not used when z holds K trajectories as (K, M, 2d)")
        za = np.asarray(z)
        ta = np.broadcast_to(np.asarray(t), za.shape[:2]) if np.ndim(t) == 1 else np.asarray(t)
        if ta.shape != za.shape[:2]:
            raise ValueError(f"t: expected shape (M,) or {za.shape[:2]} for z of shape {za.shape}")
        return list(zip(ta, za))
    zs = _samples("z", z, observed)
    ts = _checks.vector("t", t, length=zs.shape[0])
    return [(ts, zs)] if traj is None else _split_by_label(ts, zs, traj)


def trajectories(z, t, traj=None, *, observed="states", name="trajectories", dim=None):
    """The trajectory forms of `identify`, `fit_trajectories` and `Model.score` (z (M, ·) with
    t (M,); rows labelled by traj; z (K, M, ·); lists of arrays) → checked list of Trajectory
    of states or positions, as `observed` says; `dim` the columns expected, or None."""
    return trajectory_list(_split(t, z, traj, observed), name, dim, observed)


def pairs(prefix, z0, z1, h, train=False):
    """Snapshot pairs → Pairs of checked arrays; `train` refuses values too large to train
    on. The names are the arguments' with `prefix` ("validation ")."""
    a0, _ = _checks.states(f"{prefix}z0", z0, allow_single=False)
    a1, _ = _checks.states(f"{prefix}z1", z1, dim=a0.shape[1], allow_single=False)
    if train:
        trainable(f"{prefix}z0", a0)
        trainable(f"{prefix}z1", a1)
    if a1.shape[0] != a0.shape[0]:
        raise ValueError(f"{prefix}z1: has {a1.shape[0]} states, expected {a0.shape[0]} (as z0)")
    return Pairs(a0, a1, _checks.steps(f"{prefix}h", h, a0.shape[0]))


def _pairs_as_trajectories(z0, z1, h):
    """Each pair a trajectory of two samples at the times (0, h)."""
    return trajectory_list([(np.array([0.0, hj]), np.stack([a, b])) for a, b, hj in zip(z0, z1, h)],
                           "trajectories")


# --- what the layout and the clock are ------------------------------------------------------

def _layout_warning(who, ncols, stacklevel):
    d = ncols // 2
    qs = ", ".join(f"q{i}" for i in range(1, d + 1))
    ps = ", ".join(f"p{i}" for i in range(1, d + 1))
    warnings.warn(
        f"{who}: observed not given: the {ncols} columns are read as a state ({qs}, {ps}), "
        f"d = {d}; if they are {ncols} positions alone, pass observed=\"positions\" (the "
        "momenta are then fitted as hidden states); observed=\"states\" silences this",
        LayoutWarning, stacklevel=stacklevel + 1)


def _columns_of(z):
    """The number of columns of z in any accepted form, or None."""
    first = z[0] if isinstance(z, (list, tuple)) and len(z) else z
    return np.shape(first)[-1] if np.ndim(first) >= 1 else None


def observed_by_width(z, d):
    """"positions" when z (any trajectory form) has d columns (or is (M,) for d = 1) and d is
    not 2d, else "states": a model's d tells the two apart."""
    first = z[0] if isinstance(z, (list, tuple)) and len(z) else z
    width = 1 if np.ndim(first) == 1 else np.shape(first)[-1] if np.ndim(first) else None
    return "positions" if width == d and width != 2 * d else "states"


class _Layout:
    """What the caller said or a DataFrame showed: the data, the times, the layout observed
    (None: not given) and the clock's unit with where it was read."""

    def __init__(self, z, t, observed, time_unit, name):
        if time_unit is not None:
            _checks.choice("time_unit", time_unit, TIME_UNITS)
        if observed is not None:
            _checks.choice("observed", observed, OBSERVED)
        self.z, self.t, self.observed = z, t, observed
        self.time_unit, self.unit_source = time_unit, "time_unit"
        self.from_frame = _frames.is_pandas(z)
        self.frame_trajectories = False
        if self.from_frame:
            frame = _frames.unpack(z, t, observed, name)
            self.z, self.t, self.observed = frame.z, frame.t, frame.observed
            self.frame_trajectories = isinstance(frame.z, list)
            if time_unit is None and frame.time_column is not None:
                self.time_unit = _core.time_unit_of_column(frame.time_column)
                self.unit_source = f"column {frame.time_column!r}"

    def resolve(self, who, stacklevel, warn=True):
        """The layout, "states" when not given (with a LayoutWarning for an even number of
        columns when `warn`)."""
        if self.observed is None:
            ncols = _columns_of(self.z) if warn else None
            if ncols is not None and ncols % 2 == 0:
                _layout_warning(who, ncols, stacklevel)
            self.observed = "states"
        return self.observed


# --- known inputs --------------------------------------------------------------------------

def _input_rows(arrays, trajs):
    """The inputs as one (M_k, m) array per trajectory, one row per sample time."""
    out = []
    for k, (a, tr) in enumerate(zip(arrays, trajs)):
        a = _checks.real_array(f"u[{k}]", a)
        if a.ndim == 1:
            a = a[:, None]
        if a.ndim != 2 or a.shape[0] != len(tr.t):
            raise ValueError(f"u[{k}]: expected shape ({len(tr.t)},) or ({len(tr.t)}, m), one row "
                             f"per sample time; got {a.shape}")
        if not np.all(np.isfinite(a)):
            row = int(np.argwhere(~np.isfinite(a))[0][0])
            raise ValueError(f"u[{k}]: row {row} is not finite; expected finite inputs")
        out.append(np.ascontiguousarray(a))
    return out


# --- the entries ---------------------------------------------------------------------------

def read(z, t, traj, *, pairs_given=None, observed=None, u=None, time_unit=None,
         who="csympnet.identify", stacklevel=2):
    """identify's data → Records: trajectories (z, t, traj) in any form, or independent pairs
    (pairs_given = (z0, z1, h)). `stacklevel` is that of a warning issued in this function."""
    layout = _Layout(z, t, observed, time_unit, "z")
    if traj is not None and layout.frame_trajectories:
        raise ValueError("traj: the frame has a trajectory column; expected one of them")
    z, t = layout.z, layout.t
    observed = layout.resolve(who, stacklevel + 1, warn=pairs_given is None)
    if pairs_given is not None:
        if observed == "positions":
            raise ValueError('observed: "positions" needs trajectories; a pair needs a whole '
                             'state (q and p) at both ends')
        if z is not None or t is not None or traj is not None:
            raise ValueError("pairs: give either pairs=(z0, z1, h) or trajectories (z, t), not both")
        if not isinstance(pairs_given, (tuple, list)) or len(pairs_given) != 3:
            raise ValueError("pairs: expected a (z0, z1, h) triple")
        z0, _ = _checks.states("pairs z0", pairs_given[0], allow_single=False)
        z1, _ = _checks.states("pairs z1", pairs_given[1], allow_single=False)
        if z1.shape != z0.shape:
            raise ValueError(f"pairs z1: expected shape {z0.shape}, got {z1.shape}")
        h = _checks.vector("pairs h", pairs_given[2], length=z0.shape[0])
        trajs = _pairs_as_trajectories(z0, z1, h)
    else:
        if t is None:
            raise ValueError("t: the sample times are needed with trajectories (identify(z, t))")
        same_dimension("z", z, observed)
        trajs = trajectories(z, t, traj, observed=observed)
    inputs = None
    if u is not None:
        if pairs_given is not None or traj is not None:
            raise ValueError("u: known inputs go with trajectories given as arrays (z, t) or "
                             "lists of them; pairs and traj labels are not supported with inputs")
        arrays = list(u) if isinstance(u, (list, tuple)) else [u]
        if isinstance(z, (list, tuple)) != isinstance(u, (list, tuple)) or \
                len(arrays) != len(trajs):
            raise ValueError(f"u: expected one array of inputs per trajectory ({len(trajs)}), "
                             f"as z is given")
        inputs = _input_rows(arrays, trajs)
    for k, tr in enumerate(trajs):
        trainable(f"trajectory {k} z", tr.z)
    return Records(trajs, observed, pairs_given is not None, inputs, layout.time_unit,
                   layout.unit_source)


def _times(t, n_rows, step, name="t"):
    """Sample times for n_rows samples: t None (steps of `step`), a step, or the times."""
    if t is None:
        t = step
    if np.ndim(t) == 0:
        return _checks.real(name, t, positive=True) * np.arange(n_rows, dtype=float)
    return _checks.vector(name, t, length=n_rows)


def _estimator_split(x, t, step, observed, dim=None):
    """The estimator's trajectory forms (see CSympNetID.fit) as a list of (t, z) pairs: t the
    times, one step, or None (steps of `step`)."""
    if isinstance(x, (list, tuple)):
        if len(x) == 0:
            raise ValueError("x: expected at least one trajectory")
        if isinstance(t, (list, tuple)):
            if len(t) != len(x):
                raise ValueError(f"t: {len(t)} time arrays for {len(x)} trajectories")
            ts = t
        else:
            ts = [t] * len(x)
        out = []
        for k, (zk, tk) in enumerate(zip(x, ts)):
            z = _samples(f"x[{k}]", zk, observed, dim)
            out.append((_times(tk, z.shape[0], step, f"t[{k}]"), z))
        return out
    if np.ndim(x) == 3:
        xa = np.asarray(x, dtype=float)
        if t is not None and np.ndim(t) == 2:
            ta = np.asarray(t, dtype=float)
            if ta.shape != xa.shape[:2]:
                raise ValueError(f"t: expected shape {xa.shape[:2]} for x of shape {xa.shape}")
            return [(ta[k], xa[k]) for k in range(xa.shape[0])]
        return [(_times(t, xa.shape[1], step), xa[k]) for k in range(xa.shape[0])]
    z = _samples("x", x, observed, dim)
    return [(_times(t, z.shape[0], step), z)]


def _estimator_pairs(x, x_next, t, step, dim=None):
    z0, _ = _checks.states("x", x, dim=dim, allow_single=False)
    z1, _ = _checks.states("x_next", x_next, dim=z0.shape[1], allow_single=False)
    if z1.shape != z0.shape:
        raise ValueError(f"x_next: expected shape {z0.shape}, got {z1.shape}")
    return z0, z1, _checks.steps("t", step if t is None else t, z0.shape[0])


def read_estimator(x, t, *, x_next=None, u=None, observed=None, time_unit=None, t_default=None,
                   who="CSympNetID.fit", stacklevel=2):
    """CSympNetID.fit's data → Records: trajectories x with times t (the times, one step, or
    None: steps of t_default, else of 1 with a NoTimesWarning), or pairs (x, x_next) with
    steps t. `stacklevel` is that of a warning issued in this function."""
    layout = _Layout(x, t, observed, time_unit, "x")
    if layout.from_frame and x_next is not None:
        raise ValueError("x_next: pairs are arrays; a DataFrame holds trajectories")
    x, t = layout.z, layout.t
    observed = layout.resolve(who, stacklevel + 1, warn=x_next is None)
    # After a DataFrame is read: its time column gives the times.
    if t is None and t_default is None:
        warnings.warn(
            f"{who}: no times given (t) and no t_default: the samples are taken 1 "
            "time unit apart, so gamma_ is per sample, not per unit of time; pass the "
            "sample times or the step as t, or set t_default", NoTimesWarning,
            stacklevel=stacklevel)
    step = 1.0 if t_default is None else t_default
    if observed == "positions" and x_next is not None:
        raise ValueError('x_next: pairs need whole states; observed="positions" takes '
                         "trajectories of positions")
    if x_next is not None and u is not None:
        raise ValueError("u: known inputs go with trajectories; pairs (x_next) take none")
    if x_next is not None:
        trajs = _pairs_as_trajectories(*_estimator_pairs(x, x_next, t, step))
    else:
        pieces = _estimator_split(x, t, step, observed)
        same_dimension("x", [z for _, z in pieces], observed)
        trajs = trajectory_list(pieces, "trajectories", observed=observed)
    inputs = None
    if u is not None:
        if not isinstance(u, (list, tuple)):
            if len(trajs) != 1:
                raise ValueError(f"u: expected a list of {len(trajs)} input arrays, one per "
                                 "trajectory of x")
            arrays = [u]
        else:
            arrays = list(u)
            if len(arrays) != len(trajs):
                raise ValueError(f"u: expected one array of inputs per trajectory "
                                 f"({len(trajs)}), as x is given")
        inputs = _input_rows(arrays, trajs)
    for k, tr in enumerate(trajs):
        trainable(f"trajectory {k} z", tr.z)
    return Records(trajs, observed, x_next is not None, inputs, layout.time_unit,
                   layout.unit_source)


def read_estimator_score(x, t, *, x_next=None, step, dim, fitted_on_positions=False):
    """CSympNetID.score's data → list of Trajectory of states with `dim` = 2d columns (pairs
    as two-sample trajectories); without times the steps are `step`."""
    if fitted_on_positions and x_next is None and np.ndim(x) >= 1 and np.shape(x)[-1] != dim:
        raise ValueError(
            f"x: score takes states (q, p), {dim} columns; this estimator "
            "was fitted on positions alone, whose momenta are hidden: get a state from a "
            "window of positions with model_.state_from_positions(q, t), or compare "
            "simulate() with your positions")
    if x_next is not None:
        return _pairs_as_trajectories(*_estimator_pairs(x, x_next, t, step, dim))
    return trajectory_list(_estimator_split(x, t, step, "states", dim), "x", dim=dim)
