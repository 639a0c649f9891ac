"""pandas DataFrames and Series as data for `identify` and `CSympNetID.fit`, read by column
name without importing pandas (a frame is recognised by its type's module).

A DataFrame's columns:
  - a time column named t, time, times, timestamp, or one of them with a unit (t_ms,
    time_s, timestamp_us, "t [s]", "t (ms)"): the sample times, and the unit of the clock
    when its name states one (`time_unit=` still wins);
  - a column named traj or trajectory: the trajectory of each row;
  - q1..qd and p1..pd: states (observed="states");
  - q1..qd alone, or any other names: positions, in the frame's column order
    (observed="positions").
A Series is the positions of one coordinate; its index is taken as the times when it is not a
plain 0, 1, 2, ... range and no t is given.
"""

import re

import numpy as np

from . import _core

_TIME = re.compile(r"^(t|time|times|timestamp)([^a-z0-9].*|_?[a-zµ]+)?$")


def is_pandas(x):
    """True for a pandas DataFrame or Series (pandas itself is not imported)."""
    return type(x).__module__.split(".")[0] == "pandas" and hasattr(x, "to_numpy")


def _is_time_name(name):
    n = str(name).strip().lower()
    if n in ("t", "time", "times", "timestamp"):
        return True
    return bool(_TIME.match(n)) and _core.time_unit_of_column(str(name)) is not None


def _default_index(index):
    return type(index).__name__ == "RangeIndex"


class Unpacked:
    """What a frame holds: z (array or list of arrays), t (array, list or None), the observed
    layout it implies, and the name of its time column (None without one)."""

    def __init__(self, z, t, observed, time_column):
        self.z, self.t, self.observed, self.time_column = z, t, observed, time_column


def unpack(x, t, observed, who):
    """x (a DataFrame or Series) as arrays; `t` the caller's times (refused beside a time
    column); `observed` the caller's (None: from the column names)."""
    if x.ndim == 1:  # a Series: one coordinate's positions
        z = np.asarray(x.to_numpy(), dtype=float)
        time_column = None
        if t is None and not _default_index(x.index):
            t = np.asarray(x.index.to_numpy(), dtype=float)
            time_column = None if x.index.name is None else str(x.index.name)
        return Unpacked(z, t, observed or "positions", time_column)
    names = [str(c) for c in x.columns]
    time = [c for c, n in zip(x.columns, names) if _is_time_name(n)]
    traj = [c for c, n in zip(x.columns, names) if n.lower() in ("traj", "trajectory")]
    if len(time) > 1:
        raise ValueError(f"{who}: the frame has {len(time)} time columns "
                         f"({', '.join(map(str, time))}); expected one")
    if len(traj) > 1:
        raise ValueError(f"{who}: the frame has {len(traj)} trajectory columns; expected one")
    if time and t is not None:
        raise ValueError(f"{who}: the frame has a time column {str(time[0])!r} and t is given "
                         "too; expected one of them")
    data = [c for c in x.columns if (not time or c is not time[0]) and
            (not traj or c is not traj[0])]
    if not data:
        raise ValueError(f"{who}: the frame has no columns of positions or states")
    by_name = {str(c): c for c in data}
    d = len(data) // 2
    qs, ps = [f"q{i}" for i in range(1, d + 1)], [f"p{i}" for i in range(1, d + 1)]
    if observed is None:
        states = set(by_name) == set(qs + ps) and len(data) == 2 * d
        observed = "states" if states else "positions"
        if states:
            data = [by_name[n] for n in qs + ps]
    elif observed == "states" and set(by_name) == set(qs + ps) and len(data) == 2 * d:
        data = [by_name[n] for n in qs + ps]
    if observed == "positions":  # q1..qd in their numbered order, other names as given
        numbered = [f"q{i}" for i in range(1, len(data) + 1)]
        if set(by_name) == set(numbered):
            data = [by_name[n] for n in numbered]
    z = np.asarray(x[data].to_numpy(), dtype=float)
    times = np.asarray(x[time[0]].to_numpy(), dtype=float) if time else t
    time_column = str(time[0]) if time else None
    if traj:
        ids = np.asarray(x[traj[0]].to_numpy())
        order = list(dict.fromkeys(ids.tolist()))  # first appearance
        if times is None or np.ndim(times) == 0:
            raise ValueError(f"{who}: a frame with a trajectory column needs a time column")
        tt = np.asarray(times, dtype=float)
        z = [z[ids == k] for k in order]
        times = [tt[ids == k] for k in order]
    return Unpacked(z, times, observed, time_column)
