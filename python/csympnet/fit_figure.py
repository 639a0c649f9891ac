"""The figure of a `csympnet fit` output directory: OUT/fit.png and OUT/fit.pdf.

    python3 -m csympnet.fit_figure OUT [--data FILE] [--path BASE]

`csympnet fit` runs this after it has written report.json and model.json (unless
--no-figures). It reads the record named in report.json ("data": "file", with the "columns"
map of --columns), runs the fitted model freely over the record's own sample times and draws:

  - each dof's positions, record against the free run (one panel per dof up to three; with
    more dofs the first three and a summary of every dof's free-run error);
  - the residuals, record minus free run;
  - the amplitude envelope: the peaks of |q - centre| in each half-cycle of the free run, for
    the record and the free run, beside A0 exp(-gamma_hat t / 2). gamma_hat is the energy's
    decay rate (energy ~ exp(-gamma_hat t)), so amplitudes decay at gamma_hat / 2;
  - the modes (angular frequency and damping ratio with their intervals) and gamma_hat.

The free run of a record with momenta starts at its first state; for positions alone it
starts at the state that the model fits to the first window of positions
(Model.state_from_positions), at the window's last time. With several trajectories the
longest is drawn (the title says which). The record is read here with NumPy (the CSV layout
of docs/data-formats.md); the model's rollouts need the compiled module.

On failure the command prints one line, "fit_figure: WHY", to standard error and exits 1.
"""

import json
import math
import os
import re
import sys
import textwrap

import numpy as np

try:
    from . import plot
except ImportError as e:  # matplotlib missing: draw() says so in one line
    plot, _PLOT_ERROR = None, e

#: The figure's file name in the output directory, without its suffix (.png and .pdf).
FIGURE_NAME = "fit"
# Dofs drawn one panel each; beyond them a summary panel of every dof.
_MAX_DOF_PANELS = 3
# Positions fitted for the start state of a positions-only record.
_START_WINDOW = 20
_CANONICAL = re.compile(r"^(traj|t|h|[qp][1-9][0-9]*|next_[qp][1-9][0-9]*)$")
_RECORD = {"color": "black", "lw": 0.0, "marker": ".", "markersize": 2.0, "zorder": 3}


class Record:
    """One trajectory of a record: times t (n,), positions q (n, d), momenta p (n, d) or
    None (positions alone), and the file's own name of each position column."""

    def __init__(self, t, q, p, names):
        self.t, self.q, self.p, self.names = t, q, p, names


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
    use = (["traj"] if "traj" in where else []) + ["t"] + qs + (ps if has_p else [])
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
    return [Record(x[:, 0], x[:, 1:1 + d], x[:, 1 + d:] if has_p else None, names)
            for x in parts]


def free_run(model, rec):
    """(index of the first simulated sample, states (n - index, 2d)): the model iterated over
    the record's own steps, from its first state or, for positions alone, from the state
    fitted to the first window of positions (at the window's last time)."""
    if rec.p is not None:
        start, z0 = 0, np.concatenate([rec.q[0], rec.p[0]])
    else:
        start = min(len(rec.t), _START_WINDOW) - 1
        z0, _ = model.state_from_positions(rec.q[:start + 1], rec.t[:start + 1])
    hs = np.diff(rec.t[start:])
    return start, (model.rollout(z0, hs) if hs.size else z0[None, :])


def envelope(t, q_record, q_model):
    """Amplitudes per half-cycle: the free run's sign changes about its mean cut the time axis;
    in each whole half-cycle the peak |q - centre| of the record and of the free run, at its
    time. Returns (times, record peaks, model peaks, centre); empty arrays when the free run
    completes fewer than two half-cycles."""
    finite = np.isfinite(q_model)
    centre = float(np.mean(q_model[finite])) if finite.any() else 0.0
    x, y = q_record - centre, q_model - centre
    cuts = np.flatnonzero(np.diff(np.sign(y)) != 0) + 1
    ts, rec, mod = [], [], []
    for lo, hi in zip(cuts[:-1], cuts[1:]):  # whole half-cycles only
        if hi - lo < 2:
            continue
        k = lo + int(np.argmax(np.abs(y[lo:hi])))
        ts.append(t[k])
        rec.append(float(np.max(np.abs(x[lo:hi]))))
        mod.append(float(np.abs(y[k])))
    return np.array(ts), np.array(rec), np.array(mod), centre


def _interval(iv, fmt="{:#.4g}"):
    return f" [{fmt.format(iv[0])}, {fmt.format(iv[1])}]" if iv else ""


def _time_unit(report):
    unit = report.get("time_unit")
    return unit.get("unit") if isinstance(unit, dict) and unit.get("unit") else ""


def _heading(report, data, which):
    per = _time_unit(report) or "time unit"
    name = os.path.basename(data)
    g = report.get("gamma_hat")
    if report.get("identified"):
        lo, hi = report.get("gamma_ci_low"), report.get("gamma_ci_high")
        level = 100 * float(report.get("gamma_ci_level") or 0.95)
        text = (f"{name}: $\\hat\\gamma$ = {g:.4g}{_interval((lo, hi) if lo is not None else None)}"
                f" per {per} ({level:g}% interval)")
    else:
        verdict = "model rejected" if report.get("verdict") == "model rejected" else "not identified"
        text = f"{name}: $\\gamma$ {verdict}" + (f" (estimate {g:.4g} per {per})" if g is not None else "")
    return text + (f"\n{which}" if which else "")


def _modes_text(report, width=100):
    """The lines of the text panel: γ̂, the verdict and its reasons, the modes."""
    per = _time_unit(report) or "time unit"
    lines = []
    g = report.get("gamma_hat")
    if g is not None:
        iv = ((report.get("gamma_ci_low"), report.get("gamma_ci_high"))
              if report.get("identified") and report.get("gamma_ci_low") is not None else None)
        lines.append(f"damping rate γ̂ = {g:.4g}{_interval(iv)} per {per}: energy ∝ exp(−γ̂t), "
                     "amplitude ∝ exp(−γ̂t/2)")
    if not report.get("identified"):
        lines.append("γ not identified:" if report.get("verdict") != "model rejected"
                     else "model rejected:")
        for why in report.get("reasons") or []:
            wrapped = textwrap.wrap(why, width, initial_indent="  - ", subsequent_indent="    ")
            lines += wrapped[:3] + (["    ... (report.json: reasons)"] if len(wrapped) > 3 else [])
    modes = report.get("modes") or {}
    if modes.get("list"):
        lines.append(f"modes (ω in rad per {per}):")
    for k, m in enumerate(modes.get("list") or [], 1):
        lines.append(f"  {k}: ω = {m['angular_frequency']:#.4g}"
                     f"{_interval(m.get('angular_frequency_interval'))}, "
                     f"damping ratio ζ = {m['damping_ratio']:#.4g}"
                     f"{_interval(m.get('damping_ratio_interval'))}")
    if modes.get("note"):
        lines += textwrap.wrap(modes["note"], width)
    if not modes.get("list") and not modes.get("note"):
        lines.append("no oscillating mode")
    return lines


def draw(out_dir, data=None, path=None, *, model=None, size="page"):
    """The figure of the `csympnet fit` output directory `out_dir` (see the module's text).
    data: the record (default: report.json's "data" "file", relative to the working
    directory, read with its "columns" map); model: a loaded Model (default: out_dir's
    model.json). path: save as PATH.png and PATH.pdf (None: do not save). Returns the Figure."""
    if plot is None:
        raise ImportError(f"the figure needs matplotlib ({_PLOT_ERROR})")
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
    fig = _draw(report, data, rec, start, z, which, size)
    if path is not None:
        _save_atomic(fig, path)
    return fig


def _draw(report, data, rec, start, z, which, size):
    d = rec.q.shape[1]
    shown = min(d, _MAX_DOF_PANELS)
    t, ts = rec.t, rec.t[start:]
    qhat = z[:, :d]
    unit = _time_unit(report)
    tlabel = f"time ({unit})" if unit else "time (unit of the data)"
    rows = shown + 1 + (d > shown)
    width, _, preset = plot._preset(size)
    lines = _modes_text(report, width=int(0.9 * width * 72.0 / (0.6 * preset["small"])))
    text_h = len(lines) * preset["small"] * 1.45 / 72.0 + 0.15
    with plot._rc(size):
        fig = plot.Figure(figsize=(width, 1.9 * rows + text_h + 0.5), layout="constrained")
        plot.FigureCanvasAgg(fig)
        gs = fig.add_gridspec(rows + 1, 2, width_ratios=[1.6, 1.0],
                              height_ratios=[1.9] * rows + [text_h])
        for i in range(shown):
            ax = fig.add_subplot(gs[i, 0])
            ax.plot(t, rec.q[:, i], label="record", **_RECORD)
            ax.plot(ts, plot._shown(qhat[:, i]), color=plot.FEATURED_COLOR, lw=1.0,
                    label=("free run from the first state" if start == 0 else
                           f"free run from the state fitted\nto the first {start + 1} positions"),
                    zorder=4)
            if start > 0:
                ax.axvline(t[start], color="0.5", lw=0.6, ls=":")
            ax.set_ylabel(rec.names[i])
            ax.set_title(f"{rec.names[i]}: record and the model's free run")
            if i == 0:
                ax.legend(loc="best", fontsize=preset["small"], framealpha=0.85)
            res = fig.add_subplot(gs[i, 1])
            with np.errstate(invalid="ignore", over="ignore"):
                r = rec.q[start:, i] - qhat[:, i]
            res.plot(ts, plot._shown(r), color="0.25", lw=0.6)
            res.axhline(0.0, color="0.6", lw=0.5)
            res.set_title("residual, record − free run")
            res.set_ylabel(rec.names[i])
            for a in (ax, res):
                a.set_xlabel(tlabel)
                plot._style(a, size)
        row = shown
        if d > shown:
            ax = fig.add_subplot(gs[row, :])
            with np.errstate(invalid="ignore", over="ignore"):
                err = np.sqrt(np.mean((rec.q[start:] - qhat) ** 2, axis=0))
                spread = np.std(rec.q[start:], axis=0)
                rel = np.where(spread > 0, err / np.where(spread > 0, spread, 1.0), np.nan)
            ax.bar(np.arange(d), plot._shown(rel), color=plot.FEATURED_COLOR)
            ax.set_xticks(np.arange(d), rec.names, rotation=45 if d > 6 else 0,
                          fontsize=preset["small"])
            ax.set_ylabel("rms error / spread")
            ax.set_title(f"free-run error of every dof (the first {shown} drawn above)")
            plot._style(ax, size)
            ax.grid(False, axis="x")
            row += 1
        _envelope_panel(fig.add_subplot(gs[row, :]), report, rec, start, qhat, tlabel, size)
        text = fig.add_subplot(gs[row + 1, :])
        text.axis("off")
        text.text(0.0, 1.0, "\n".join(lines), ha="left", va="top", fontsize=preset["small"],
                  transform=text.transAxes, in_layout=False)
        fig.suptitle(_heading(report, data, which))
    return fig


def window_rms(t, q_record, q_model, period):
    """Amplitudes over consecutive windows of length `period` (the slowest mode's): the rms of
    ‖q − centre‖ over the dofs, for the record and the free run, at each window's middle time.
    A sum of modes that each decay as exp(−γt/2) has an rms over a period that decays so too."""
    finite = np.isfinite(q_model).all(axis=1)
    centre = np.mean(q_model[finite], axis=0) if finite.any() else np.zeros(q_model.shape[1])
    edges = np.arange(t[0], t[-1] + 1e-12 * abs(t[-1]), period)
    ts, rec, mod = [], [], []
    for lo, hi in zip(edges[:-1], edges[1:]):
        k = (t >= lo) & (t < hi)
        if k.sum() < 2:
            continue
        ts.append(float(np.mean(t[k])))
        rec.append(float(np.sqrt(np.mean(np.sum((q_record[k] - centre) ** 2, axis=1)))))
        mod.append(float(np.sqrt(np.mean(np.sum((q_model[k] - centre) ** 2, axis=1)))))
    return np.array(ts), np.array(rec), np.array(mod)


def _envelope_panel(ax, report, rec, start, qhat, tlabel, size):
    """The amplitude, record and free run, with the fitted A0 exp(−γ̂ t/2): for one dof the
    peak per half-cycle; for several, the rms of ‖q − centre‖ over windows of one period of the
    slowest mode (per-dof peaks beat between modes)."""
    ts = rec.t[start:]
    omegas = [m["angular_frequency"] for m in (report.get("modes") or {}).get("list") or []
              if m.get("angular_frequency", 0) > 0]
    d = rec.q.shape[1]
    period = 2 * math.pi / min(omegas) if omegas else 0.0
    if d > 1 and 0 < period <= (ts[-1] - ts[0]) / 2:
        tk, rec_peaks, mod_peaks = window_rms(ts, rec.q[start:], qhat, period)
        ax.set_title(f"rms amplitude of q1..q{d} over windows of one period of the slowest mode")
        ylabel = "rms ‖q − centre‖\n(log scale)"
    else:
        finite = np.isfinite(qhat).all(axis=1)
        spread = np.std(qhat[finite], axis=0) if finite.any() else np.zeros(d)
        i = int(np.argmax(spread))
        tk, rec_peaks, mod_peaks, centre = envelope(ts, rec.q[start:, i], qhat[:, i])
        ax.set_title(f"amplitude of {rec.names[i]} per half-cycle")
        sign = "−" if centre >= 0 else "+"
        ylabel = f"|{rec.names[i]} {sign} {abs(centre):.3g}|\n(log scale)"
    ax.set_xlabel(tlabel)
    if tk.size < 2:
        ax.text(0.5, 0.5, "the free run completes fewer than two half-cycles: no envelope",
                ha="center", va="center", transform=ax.transAxes, in_layout=False)
        ax.set_yticks([])
        plot._style(ax, size)
        return
    ax.plot(tk, rec_peaks, "o", color="black", ms=2.5, label="record", zorder=3)
    ax.plot(tk, mod_peaks, "-", color=plot.FEATURED_COLOR, lw=1.0, label="free run", zorder=4)
    g = report.get("gamma_hat")
    good = rec_peaks > 0
    if g is not None and good.any():
        # A0 by least squares on log amplitudes with the slope fixed at -γ̂/2.
        a0 = math.exp(float(np.mean(np.log(rec_peaks[good]) + 0.5 * g * (tk[good] - tk[0]))))
        tt = np.linspace(tk[0], tk[-1], 200)
        ax.plot(tt, a0 * np.exp(-0.5 * g * (tt - tk[0])), color="#1f77b4", ls="--", lw=1.1,
                label=f"$A_0\\,e^{{-\\hat\\gamma t/2}}$, $\\hat\\gamma$ = {g:.4g}", zorder=5)
    ax.set_yscale("log")
    ax.set_ylabel(ylabel)
    ax.legend(loc="best", fontsize=plot._preset(size)[2]["small"], framealpha=0.85)
    plot._style(ax, size)


def _save_atomic(fig, path, dpi=200):
    """PATH.png and PATH.pdf, each written under a temporary name and renamed over its target,
    so that a reader (or an interrupted draw) never leaves half a file. The PDF carries no
    creation date, so the same fit gives the same bytes."""
    base = os.fspath(path)
    root, ext = os.path.splitext(base)
    if ext.lower() in (".png", ".pdf"):
        base = root
    folder, name = os.path.split(base)
    if folder:
        os.makedirs(folder, exist_ok=True)
    written = []
    with plot.rc_context(plot._TRUETYPE):
        for suffix, meta in ((".png", {}), (".pdf", {"CreationDate": None})):
            tmp = os.path.join(folder, f".{name}{suffix}.tmp.{os.getpid()}")
            try:
                fig.savefig(tmp, format=suffix[1:], dpi=dpi, metadata=meta)
                os.replace(tmp, base + suffix)
            finally:
                if os.path.exists(tmp):
                    os.remove(tmp)
            written.append(base + suffix)
    return written


def main(argv=None):
    import argparse

    parser = argparse.ArgumentParser(
        prog="python3 -m csympnet.fit_figure",
        description="Draws OUT/fit.png and OUT/fit.pdf from a `csympnet fit` output directory.")
    parser.add_argument("out", help="the output directory of `csympnet fit`")
    parser.add_argument("--data", help="the record (default: report.json's data file)")
    parser.add_argument("--path", help="save as PATH.png and PATH.pdf (default: OUT/fit)")
    args = parser.parse_args(argv)
    try:
        draw(args.out, args.data, args.path or os.path.join(args.out, FIGURE_NAME))
    except KeyboardInterrupt:
        print("fit_figure: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # one line for the CLI's note; the traceback helps no user
        text = " ".join(str(e).split()) or type(e).__name__
        print(f"fit_figure: {text}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
