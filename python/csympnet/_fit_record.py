"""What the figure of a `csympnet fit` output directory shows, read without drawing it: the
report, the record (read again with NumPy: the CSV layout of docs/data-formats.md, with fit's
--columns map applied) and the model's free run over the record's own sample times, which
needs the compiled module. `plot.fit_figure` draws it; `python3 -m csympnet.fit_figure` is its
command. Kept apart from plot.py, which draws from arrays alone, so that plot never imports
the module that imports it.
"""

import json
import os
import re
from collections import namedtuple

import numpy as np

# Positions fitted for the start state of a positions-only record.
_START_WINDOW = 20
_CANONICAL = re.compile(r"^(traj|t|h|[qpu][1-9][0-9]*|next_[qp][1-9][0-9]*)$")
# Angular frequencies of a driven model's frequency response in the figure.
_RESPONSE_POINTS = 400

FitRun = namedtuple("FitRun", "report data rec which start z response")
FitRun.__doc__ = """What the figure draws: the report (dict), the record's file name, the
trajectory drawn (a Record), which one it is in words ("" for the only one), the index of the
free run's first sample, the free run's states (n - start, 2d), and for a driven model its
linearised frequency response (Model.frequency_response's dict; None for a free model)."""


class Record:
    """One trajectory of a record: times t (n,), positions q (n, d), momenta p (n, d) or
    None (positions alone), known inputs u (n, m) or None, and the file's own name of each
    position column."""

    def __init__(self, t, q, p, names, u=None):
        self.t, self.q, self.p, self.names, self.u = t, q, p, names, u


def _column_map(spec):
    """{file's name: canonical name} from "t=time_s,q1=angle_deg" (the --columns text)."""
    out = {}
    for entry in (spec or "").split(","):
        if entry.strip():
            key, _, value = entry.partition("=")
            out[value.strip()] = key.strip()
    return out


def read_record(path, columns=""):
    """The trajectories of a trajectories or positions CSV, as a list of Record, with the
    --columns map `columns` applied as `fit` applies it (mapped columns renamed, other
    non-canonical columns dropped). A pairs file holds no record and is refused."""
    if not os.path.exists(path):
        raise ValueError(f"{path}: not found (a relative name is read from the working "
                         "directory; give the record as --data FILE)")
    if not os.path.isfile(path):
        raise ValueError(f"{path}: not a regular file (the figure reads the record again)")
    with open(path, encoding="utf-8-sig") as f:
        header, skip = "", 0
        for line in f:
            skip += 1
            if line.strip():
                header = line
                break
    fields = [s.strip() for s in header.split(",")]
    own = _column_map(columns)
    taken = set(own.values())  # a mapped name hides a column of the file spelled as it
    canonical = [own[s] if s in own else s if _CANONICAL.match(s) and s not in taken else None
                 for s in fields]
    where = {c: i for i, c in enumerate(canonical) if c is not None}
    if "h" in where:
        raise ValueError(f"{path}: a pairs file holds no record to simulate")
    d = sum(1 for c in where if re.fullmatch(r"q[0-9]+", c))
    if "t" not in where or d == 0:
        raise ValueError(f"{path}: expected a header '[traj,]t,q1..qd[,p1..pd]', got {header!r}")
    qs = [f"q{i}" for i in range(1, d + 1)]
    ps = [f"p{i}" for i in range(1, d + 1)]
    has_p = all(c in where for c in ps)
    m = sum(1 for c in where if re.fullmatch(r"u[0-9]+", c))
    us = [f"u{j}" for j in range(1, m + 1)]
    if any(c not in where for c in us):
        raise ValueError(f"{path}: input columns must be u1..um in order, got {header!r}")
    use = (["traj"] if "traj" in where else []) + ["t"] + qs + (ps if has_p else []) + us
    a = np.loadtxt(path, delimiter=",", skiprows=skip, usecols=[where[c] for c in use],
                   ndmin=2, encoding="utf-8-sig")
    back = {v: k for k, v in own.items()}
    names = [back.get(c, c) for c in qs]
    if "traj" in where:
        ids, a = a[:, 0], a[:, 1:]
        cuts = np.flatnonzero(np.diff(ids) != 0) + 1
        parts = np.split(a, cuts)
    else:
        parts = [a]
    k = 1 + d + (d if has_p else 0)
    return [Record(x[:, 0], x[:, 1:1 + d], x[:, 1 + d:1 + 2 * d] if has_p else None, names,
                   x[:, k:k + m] if m else None)
            for x in parts]


def free_run(model, rec):
    """(index of the first simulated sample, states (n - index, 2d)): the model iterated over
    the record's own steps, from its first state or, for positions alone, from the state
    fitted to the first window of positions (at the window's last time). A driven model is
    fed the record's inputs, from the state fitted to the first window of positions (its
    momenta set aside, as fit sets them aside)."""
    if model.n_inputs > 0:
        if rec.u is None or rec.u.shape[1] != model.n_inputs:
            raise ValueError(f"the model is driven by {model.n_inputs} input(s); the record "
                             "has no such u columns")
        start = min(len(rec.t), _START_WINDOW) - 1
        z0, _ = model.state_from_positions(rec.q[:start + 1], rec.t[:start + 1],
                                           u=rec.u[:start + 1])
        if start + 1 == len(rec.t):
            return start, z0[None, :]
        return start, model.simulate(z0, rec.t[start:], rec.u[start:])
    if rec.p is not None:
        start, z0 = 0, np.concatenate([rec.q[0], rec.p[0]])
    else:
        start = min(len(rec.t), _START_WINDOW) - 1
        z0, _ = model.state_from_positions(rec.q[:start + 1], rec.t[:start + 1])
    hs = np.diff(rec.t[start:])
    return start, (model.rollout(z0, hs) if hs.size else z0[None, :])


def read_fit(out_dir, data=None, model=None):
    """The FitRun of the output directory `out_dir`: its report.json, the record (default:
    the report's "data" "file", relative to the working directory, read with its "columns"
    map; of several trajectories the first of the longest) and the free run of `model`
    (default: out_dir's model.json)."""
    with open(os.path.join(out_dir, "report.json"), encoding="utf-8") as f:
        report = json.load(f)
    info = report.get("data") if isinstance(report.get("data"), dict) else {}
    data = data if data is not None else info.get("file")
    if not data or data == "-":
        raise ValueError("the record was read from standard input; pass the file as data=")
    if model is None:
        from ._model import load  # the compiled module: only the rollouts need it
        model = load(os.path.join(out_dir, "model.json"))
    recs = read_record(data, info.get("columns", ""))
    k = max(range(len(recs)), key=lambda i: len(recs[i].t))  # the first of the longest
    rec = recs[k]
    if len(rec.t) < 2:
        raise ValueError(f"{data}: the longest trajectory has {len(rec.t)} sample")
    if rec.q.shape[1] != model.d:
        raise ValueError(f"{data}: {rec.q.shape[1]} positions per row, the model has d = {model.d}")
    which = f"trajectory {k + 1} of {len(recs)} (the longest)" if len(recs) > 1 else ""
    start, z = free_run(model, rec)
    return FitRun(report, data, rec, which, start, z, frequency_response(model, report, rec))


def frequency_response(model, report, rec):
    """A driven model's linearised frequency response over the angular frequencies from a
    fifth of its slowest mode (or of the record's lowest frequency) to three times its fastest,
    below 0.9 of the Nyquist frequency, at the record's median step; None for a free model or
    one without an equilibrium near the origin (the figure then leaves the panel out)."""
    if model.n_inputs == 0:
        return None
    h = float(np.median(np.diff(rec.t)))
    modes = [m["angular_frequency"] for m in (report.get("modes") or {}).get("list", [])
             if isinstance(m, dict) and m.get("angular_frequency")]
    span = float(rec.t[-1] - rec.t[0])
    lo = 0.2 * min(modes) if modes else 2 * np.pi / max(span, h)
    hi = min(3.0 * max(modes) if modes else 0.5 * np.pi / h, 0.9 * np.pi / h)
    if not (0 < lo < hi):
        return None
    try:
        return model.frequency_response(np.geomspace(lo, hi, _RESPONSE_POINTS), h)
    except ValueError:
        return None
