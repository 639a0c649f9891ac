"""The paper's figure types from plain NumPy arrays and dicts.

Depends on NumPy and matplotlib only (not on the compiled csympnet module), so a script can load
this file by path. Figures are built on matplotlib's Agg canvas without pyplot, so importing it
never changes the backend of the calling program, and every setting it needs (font sizes,
TrueType fonts in PDF files) is applied in a local rc_context: the caller's rcParams are never
changed.

Conventions: a trajectory of states is an array (n+1, 2d) whose columns are q1..qd, p1..pd;
`predictions` is a dict {label: states}; model type names ("csympnet", "map", ...) are shown
with the paper's names. Every function takes `ax=` (draw into an existing Axes), `size=` (the
figure size preset, see SIZES) and `path=` (save the figure as PNG and PDF, see `save`) and
returns the matplotlib Figure.

Style: the reference is black and dashed, the featured model (`highlight=`, by default
CSympNet-ID when it is among the labels) is a thick red solid line, and both are drawn above
the other models, which are thinner and lighter. Legends list the reference, the featured
model, then the others in the order given.

Functions (signatures in docs/python.md): phase_portrait, trajectory, accumulated_error, energy,
rollout_figure, accumulated_errors, bars, error_vs_noise, lambda_vs_noise, noise_labels,
summarize, frequency_response, save; fit_figure (the figure of a `csympnet fit` output directory, which alone
needs the compiled module, for the model's rollouts).
"""

import math
import os
import textwrap

import numpy as np
from matplotlib import rc_context
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

#: The paper's names of the model types.
MODEL_NAMES = {
    "csympnet": "CSympNet-ID", "sympnet": "SympNet", "map": "MapBaseline", "ode": "ODEBaseline",
    "dhnn": "DHNN", "dhnn2": "DHNN2", "phnn": "pHNN", "phnn2": "pHNN2",
}

#: Figure size presets: width in inches (a journal's single column and full text width) and
#: font sizes in points. `size=` takes one of these names or a (width, height) tuple in inches.
SIZES = {
    "column": {"width": 3.5, "font": 8, "small": 7, "legend_columns": 3},
    "page": {"width": 7.2, "font": 9, "small": 8, "legend_columns": 5},
}

#: Units shown in axis labels, by quantity: t (time), q and p (states), H (energy), E (the
#: accumulated L2 error, whose unit is that of the states times the square root of time's).
#: Override with `units={"t": "s", ...}`; an empty string shows no unit. When E is not given
#: but t, q or p are, E's unit is made from them ("m s$^{1/2}$"; "(deg, deg/s) s$^{1/2}$"
#: when q and p differ, since E sums both).
DEFAULT_UNITS = {"t": "a.u.", "q": "a.u.", "p": "a.u.", "H": "a.u.", "E": "a.u."}

#: The featured model's colour.
FEATURED_COLOR = "#d62728"
#: The colour of each model type when it is not featured, the same in every figure.
MODEL_COLORS = {
    "sympnet": "#1f77b4", "map": "#2ca02c", "ode": "#ff7f0e", "dhnn": "#9467bd",
    "dhnn2": "#8c564b", "phnn": "#e377c2", "phnn2": "#7f7f7f", "csympnet": "#17becf",
}
# Other labels take these in turn, after the model types' colours.
_COLORS = list(MODEL_COLORS.values()) + ["#bcbd22", "#393b79", "#637939", "#8c6d31", "#843c39"]

# Line styles: the reference and the featured model above the rest (zorder), the reference
# dashed on top so that a featured curve lying on it still shows through the gaps.
_REFERENCE = {"color": "black", "ls": "--", "lw": 1.1, "zorder": 6}
_FEATURED = {"color": FEATURED_COLOR, "ls": "-", "lw": 2.0, "zorder": 5, "alpha": 1.0}
_OTHER = {"ls": "-", "lw": 0.9, "zorder": 2, "alpha": 0.8}
# Models that are not featured also differ by dash pattern and by open markers, placed at
# staggered positions along each curve, so that curves lying on one another (the Hamiltonian
# baselines on S1) each stay visible; the same pattern for a model type in every figure.
_DASHES = ["-", (0, (5, 1.5)), (0, (1.5, 1.2)), (0, (6, 1.5, 1.5, 1.5)), (0, (3, 1.5)),
           (0, (8, 2)), (0, (1, 1, 1, 1, 4, 1)), (0, (2, 2))]
_MARKERS = ["o", "s", "^", "v", "D", "x", "+", "<", ">", "p"]
_MODEL_ORDER = list(MODEL_COLORS)

# PDF and PostScript text as embedded TrueType (Type 42) fonts, which journals' submission
# systems accept, instead of matplotlib's default Type 3 fonts.
_TRUETYPE = {"pdf.fonttype": 42, "ps.fonttype": 42}


def _preset(size):
    """(width, height or None, preset dict) of a size preset name or a (width, height) tuple."""
    if isinstance(size, str):
        if size not in SIZES:
            raise ValueError(
                f"size: expected one of {sorted(SIZES)} or (width, height), got {size!r}")
        return SIZES[size]["width"], None, SIZES[size]
    try:
        w, h = (float(v) for v in size)
    except (TypeError, ValueError):
        raise ValueError(f"size: expected one of {sorted(SIZES)} or (width, height), got {size!r}")
    if not (w > 0 and h > 0):
        raise ValueError(f"size: width and height must be positive, got {size!r}")
    return w, h, SIZES["column" if w < 5.0 else "page"]


def _rc(size):
    """The local settings of a figure of size preset `size`."""
    p = _preset(size)[2]
    return rc_context({
        **_TRUETYPE,
        "font.size": p["font"], "axes.titlesize": p["font"], "axes.labelsize": p["font"],
        "legend.fontsize": p["small"], "xtick.labelsize": p["small"],
        "ytick.labelsize": p["small"], "figure.titlesize": p["font"] + 1,
        "axes.linewidth": 0.6, "xtick.major.width": 0.6, "ytick.major.width": 0.6,
        "xtick.minor.width": 0.4, "ytick.minor.width": 0.4, "grid.linewidth": 0.4,
        "lines.markersize": 3.5, "patch.linewidth": 0.5,
        "figure.constrained_layout.h_pad": 0.02, "figure.constrained_layout.w_pad": 0.02,
    })


def _name(label):
    return MODEL_NAMES.get(label, str(label))


def _units(units):
    if units is None:
        return dict(DEFAULT_UNITS)
    if not isinstance(units, dict):
        raise TypeError("units: expected a dict such as {'t': 's', 'q': 'm'}")
    unknown = sorted(set(units) - set(DEFAULT_UNITS))
    if unknown:
        raise ValueError(f"units: unknown quantities {unknown}; known: {sorted(DEFAULT_UNITS)}")
    out = {**DEFAULT_UNITS, **{k: str(v) for k, v in units.items()}}
    if "E" not in units and any(k in units for k in ("t", "q", "p")):
        out["E"] = _error_unit(out["q"], out["p"], out["t"])
    return out


def _error_unit(q, p, t):
    """The unit of E = (Σ‖z − ẑ‖² Δt)^{1/2}: the states' unit times the square root of time's."""
    states = q if q == p else f"({q}, {p})" if q and p else q or p
    if not t:
        return states
    return f"{states} {t}$^{{1/2}}$" if states else f"{t}$^{{1/2}}$"


def _label(text, unit="", log=False, wrap=26):
    """An axis label with its unit and whether the axis is logarithmic: "E (a.u., log scale)".
    A unit already in parentheses at the end of `text` is kept; a label longer than `wrap`
    characters puts the parenthesis on a second line."""
    notes = [n for n in (unit, "log scale" if log else "") if n]
    if text.endswith(")") and " (" in text:
        at = text.rindex(" (")
        text, notes = text[:at], [text[at + 2:-1]] + notes
    if not notes:
        return text
    note = f"({', '.join(notes)})"
    if len(note) > wrap and len(notes) > 1:  # too long for one line: the unit, then the rest
        note = f"({notes[0]},\n{', '.join(notes[1:])})"
    return f"{text}\n{note}" if len(text) + len(note) > wrap else f"{text} {note}"


def _featured(labels, highlight):
    """The featured label among `labels`: `highlight`, or "csympnet" when present (None), or
    nothing (False or "")."""
    labels = list(labels)
    if highlight is None:
        return "csympnet" if "csympnet" in labels else None
    if highlight is False or highlight == "":
        return None
    if highlight not in labels:
        raise ValueError(f"highlight: {highlight!r} is not one of the labels {labels}")
    return highlight


def _styles(labels, featured):
    """{label: line style}: the featured one strong and on top; the others thinner, a model
    type in its own colour (MODEL_COLORS), any other label in the next colour not yet taken."""
    labels = list(labels)
    taken = {MODEL_COLORS[k] for k in labels if k in MODEL_COLORS and k != featured}
    free = iter([c for c in _COLORS if c not in taken] or _COLORS)
    others = [k for k in labels if k != featured]
    out = {}
    for label in labels:
        if label == featured:
            out[label] = dict(_FEATURED)
        else:
            color = MODEL_COLORS.get(label) or next(free, None)
            if color is None:  # more labels than colours: start again
                free = iter(_COLORS)
                color = next(free)
            k = (_MODEL_ORDER.index(label) if label in MODEL_COLORS
                 else len(_MODEL_ORDER) + others.index(label))
            j = others.index(label)
            out[label] = {**_OTHER, "color": color, "ls": _DASHES[k % len(_DASHES)],
                          "marker": _MARKERS[k % len(_MARKERS)], "markersize": 3.2,
                          "fillstyle": "none", "markeredgewidth": 0.7,
                          "zorder": 2 + 0.01 * j, "_stagger": (j, len(others))}
    return out


def _line_style(style, n_points):
    """A _styles entry as matplotlib's keywords for a curve of n_points: markers every tenth
    of the curve, the j-th of n curves starting j/n of that spacing later, so that markers of
    curves lying on one another sit side by side."""
    out = {k: v for k, v in style.items() if k != "_stagger"}
    if "_stagger" in style and n_points > 1:
        j, n = style["_stagger"]
        step = max(1, n_points // 10)
        out["markevery"] = ((j * step) // max(n, 1), step)
    return out


def _legend_order(handles, featured):
    """Legend entries: the reference, the featured model, then the others as drawn."""
    def rank(item):
        label = item[0]
        return 0 if label == "reference" else 1 if label == featured else 2
    return sorted(handles, key=rank)  # stable: the others keep their order


def _figure(size, n_panels=1, *, ncols=1, aspect=0.75, entries=0, caption_h=0.0):
    """A figure of `n_panels` panels on a grid of `ncols` columns, sized by the preset: panels
    are width/ncols wide and aspect times that high. With legend entries, a legend axes: the
    grid's free cell when there is one, else a row below the panels.
    With caption_h > 0, a last row that high (inches) for a caption: the axes
    `figure.caption_ax`. Returns (figure, [axes], legend axes or None)."""
    width, height, p = _preset(size)
    ncols = max(1, min(ncols, n_panels))
    nrows = math.ceil(n_panels / ncols)
    free = nrows * ncols - n_panels
    in_slot = entries > 0 and free > 0
    legend_rows = 0
    if entries > 0 and not in_slot:
        per_row = min(entries, p["legend_columns"])
        legend_rows = math.ceil(entries / per_row)
    legend_h = (0.08 + legend_rows * p["small"] * 1.55 / 72.0) if legend_rows else 0.0
    if ncols == 1 and width >= 5.0:  # a single panel across the page: flatter
        aspect *= 0.6
    panel_h = width / ncols * aspect
    if height is not None:  # an explicit (width, height): the panels share what the legend leaves
        panel_h = max(height - legend_h, 0.5) / nrows
    fig = Figure(figsize=(width, nrows * panel_h + legend_h + caption_h), layout="constrained")
    FigureCanvasAgg(fig)
    ratios = [panel_h] * nrows + ([legend_h] if legend_h else []) + ([caption_h] if caption_h else [])
    gs = fig.add_gridspec(len(ratios), ncols, height_ratios=ratios)
    axes = [fig.add_subplot(gs[i // ncols, i % ncols]) for i in range(n_panels)]
    legend_ax = None
    if in_slot:
        legend_ax = fig.add_subplot(gs[nrows - 1, ncols - free:])
    elif legend_h:
        legend_ax = fig.add_subplot(gs[nrows, :])
    if legend_ax is not None:
        legend_ax.axis("off")
        legend_ax.in_slot = in_slot  # read by _put_legend
    fig.caption_ax = None
    if caption_h:
        fig.caption_ax = fig.add_subplot(gs[len(ratios) - 1, :])
        fig.caption_ax.axis("off")
    return fig, axes, legend_ax


def _new_axes(ax, size, aspect, entries):
    """(figure, axes, legend axes): the given axes (its legend inside), or a new one-panel
    figure with its legend below."""
    if ax is not None:
        return ax.figure, ax, None
    fig, axes, legend_ax = _figure(size, aspect=aspect, entries=entries)
    return fig, axes[0], legend_ax


def _legend(ax, legend_ax, size, labels, featured):
    """The legend of `ax`, in legend order: inside `ax` or in `legend_ax`."""
    items = _legend_order(_entries(ax, labels), featured)
    if items:
        _put_legend(ax if legend_ax is None else legend_ax, [h for _, h in items],
                    [lab for lab, _ in items], size, inside=legend_ax is None)


def _entries(ax, labels):
    """[(label, handle)] of the legend entries of `ax`, by the labels they were drawn for."""
    by_name = {_name(label): label for label in labels}
    by_name["reference"] = "reference"
    handles, names = ax.get_legend_handles_labels()
    return [(by_name.get(name, name), h) for h, name in zip(handles, names)]


def _put_legend(target, handles, labels, size, *, inside):
    """A legend inside the axes `target` (loc="best"), or filling a legend axes: one or two
    columns in a free cell of the grid, up to the preset's number of columns in a row."""
    p = _preset(size)[2]
    shown = [_display(lab) for lab in labels]
    if inside:
        target.legend(handles, shown, loc="best", fontsize=p["small"], framealpha=0.85)
        return
    if getattr(target, "in_slot", False):
        ncol = 1 if len(shown) <= 6 else 2
    else:
        rows = math.ceil(len(shown) / p["legend_columns"])
        ncol = math.ceil(len(shown) / rows)
    target.legend(handles, shown, loc="center", ncol=ncol, fontsize=p["small"], frameon=False,
                  handlelength=2.2, columnspacing=1.2, borderaxespad=0.0)


def _display(label):
    """A legend entry's text: the paper's name of a model type; "reference" and math as given."""
    text = str(label)
    return text if text == "reference" or text.startswith("$") else _name(label)


def _style(ax, size):
    p = _preset(size)[2]
    ax.title.set_fontsize(p["font"])
    ax.xaxis.label.set_fontsize(p["font"])
    ax.yaxis.label.set_fontsize(p["font"])
    ax.tick_params(labelsize=p["small"])
    ax.grid(True, which="major", alpha=0.3)
    return ax.figure


def _states(name, z):
    a = np.asarray(z, dtype=float)
    if a.ndim != 2 or a.shape[1] < 2 or a.shape[1] % 2:
        raise ValueError(f"{name}: expected states of shape (n+1, 2d), got {a.shape}")
    return a


def _shown(a):
    """Non-finite values (a blown-up rollout) become gaps in a line instead of breaking the
    axis scaling."""
    a = np.asarray(a, dtype=float)
    return np.where(np.isfinite(a), a, np.nan)


def _times(t, n):
    a = np.asarray(t, dtype=float)
    if a.ndim != 1 or a.shape[0] != n:
        raise ValueError(f"t: expected {n} times (one per state), got shape {a.shape}")
    return a


def _predictions(predictions):
    if not isinstance(predictions, dict):
        raise TypeError("predictions: expected a dict {label: states (n+1, 2d)}")
    return {k: _states(f"predictions[{k!r}]", v) for k, v in predictions.items()}


def _spans_decades(values, ratio=100.0):
    v = np.asarray([x for x in np.ravel(values) if np.isfinite(x) and x > 0])
    return v.size > 1 and v.max() / v.min() >= ratio


def _log_scale(ax, log, values):
    if log is None:
        log = _spans_decades(values)
    if log:
        ax.set_yscale("log", nonpositive="clip")
    return log


def _curves(ax, series, reference, featured):
    """Draws {label: (x, y)} and the reference (x, y) or None in the house style."""
    styles = _styles(series, featured)
    for label, (x, y) in series.items():
        ax.plot(x, y, label=_name(label), **_line_style(styles[label], len(x)))
    if reference is not None:
        ax.plot(*reference, label="reference", **_REFERENCE)


def save(fig, path, dpi=300):
    """Writes `fig` as PATH.png and PATH.pdf (a .png/.pdf suffix on `path` is dropped), creating
    the directory; the PDF embeds its fonts as TrueType. Returns the two paths written."""
    base, ext = os.path.splitext(os.fspath(path))
    if ext.lower() not in (".png", ".pdf"):
        base = os.fspath(path)
    folder = os.path.dirname(base)
    if folder:
        os.makedirs(folder, exist_ok=True)
    written = []
    with rc_context(_TRUETYPE):
        for suffix in (".png", ".pdf"):
            fig.savefig(base + suffix, dpi=dpi)
            written.append(base + suffix)
    return written


def _finish(fig, path):
    if path is not None:
        save(fig, path)
    return fig


def phase_portrait(predictions, reference=None, *, coord=0, highlight=None, units=None,
                   size="column", ax=None, path=None, title=None):
    """Phase portrait (q_i, p_i) of coordinate i = coord + 1 (default q1, p1).

    predictions: {label: states (n+1, 2d)}; reference: states (n+1, 2d) or None.
    """
    with _rc(size):
        preds = _predictions(predictions)
        featured = _featured(preds, highlight)
        u = _units(units)
        fig, ax, legend_ax = _new_axes(ax, size, 0.85, len(preds) + (reference is not None))
        series = {}
        for label, z in preds.items():
            d = z.shape[1] // 2
            series[label] = (_shown(z[:, coord]), _shown(z[:, d + coord]))
        ref = None
        if reference is not None:
            r = _states("reference", reference)
            d = r.shape[1] // 2
            ref = (_shown(r[:, coord]), _shown(r[:, d + coord]))
            ax.plot(r[0, coord], r[0, d + coord], "ko", zorder=7)
        _curves(ax, series, ref, featured)
        ax.set_xlabel(_label(f"$q_{{{coord + 1}}}$", u["q"]))
        ax.set_ylabel(_label(f"$p_{{{coord + 1}}}$", u["p"]))
        ax.set_title(title or "Phase portrait")
        _legend(ax, legend_ax, size, preds, featured)
        return _finish(_style(ax, size), path)


def trajectory(t, predictions, reference=None, *, coord=0, highlight=None, units=None,
               size="column", ax=None, path=None, title=None):
    """q_i(t) for coordinate i = coord + 1 (default q1). t: times (n+1,)."""
    with _rc(size):
        preds = _predictions(predictions)
        featured = _featured(preds, highlight)
        u = _units(units)
        fig, ax, legend_ax = _new_axes(ax, size, 0.6, len(preds) + (reference is not None))
        series = {label: (_times(t, z.shape[0]), _shown(z[:, coord])) for label, z in preds.items()}
        ref = None
        if reference is not None:
            r = _states("reference", reference)
            ref = (_times(t, r.shape[0]), _shown(r[:, coord]))
        _curves(ax, series, ref, featured)
        ax.set_xlabel(_label("time $t$", u["t"]))
        ax.set_ylabel(_label(f"$q_{{{coord + 1}}}$", u["q"]))
        ax.set_title(title or f"Trajectory $q_{{{coord + 1}}}(t)$")
        _legend(ax, legend_ax, size, preds, featured)
        return _finish(_style(ax, size), path)


def accumulated_errors(t, predictions, reference):
    """E(t_n) = (Σ_{k=1..n} ‖z(t_k) − ẑ(t_k)‖² (t_k − t_{k−1}))^{1/2}, so E at the last time is
    the protocol's L2 rollout error of that trajectory. Returns {label: (n+1,)} (E(t_0) = 0)."""
    ref = _states("reference", reference)
    ts = _times(t, ref.shape[0])
    dt = np.r_[0.0, np.diff(ts)]
    out = {}
    for label, z in _predictions(predictions).items():
        if z.shape != ref.shape:
            raise ValueError(
                f"predictions[{label!r}]: shape {z.shape} differs from the reference's {ref.shape}")
        with np.errstate(over="ignore", invalid="ignore"):
            out[label] = np.sqrt(np.cumsum(np.sum((z - ref) ** 2, axis=1) * dt))
    return out


def accumulated_error(t, predictions, reference, *, log=None, highlight=None, units=None,
                      size="column", ax=None, path=None, title=None):
    """Accumulated rollout error E(t) (see `accumulated_errors`); log scale when it spans
    decades (log=None), or as forced by log=True/False."""
    with _rc(size):
        errs = accumulated_errors(t, predictions, reference)
        featured = _featured(errs, highlight)
        u = _units(units)
        fig, ax, legend_ax = _new_axes(ax, size, 0.6, len(errs))
        ts = _times(t, _states("reference", reference).shape[0])
        _curves(ax, {label: (ts[1:], _shown(e[1:])) for label, e in errs.items()}, None, featured)
        log = _log_scale(ax, log, np.concatenate([e[1:] for e in errs.values()]) if errs else [])
        ax.set_xlabel(_label("time $t$", u["t"]))
        ax.set_ylabel(_label("$L^2$ error $E(t)$", u["E"], log))
        ax.set_title(title or "Accumulated error")
        _legend(ax, legend_ax, size, errs, featured)
        return _finish(_style(ax, size), path)


def energy(t, energies, reference=None, *, log=None, highlight=None, units=None, size="column",
           ax=None, path=None, title=None):
    """Energy H along rollouts. energies: {label: (n+1,)}; reference: (n+1,) or None."""
    if not isinstance(energies, dict):
        raise TypeError("energies: expected a dict {label: energy values (n+1,)}")
    with _rc(size):
        featured = _featured(energies, highlight)
        u = _units(units)
        fig, ax, legend_ax = _new_axes(ax, size, 0.6, len(energies) + (reference is not None))
        series, values = {}, []
        for label, e in energies.items():
            e = np.asarray(e, dtype=float)
            series[label] = (_times(t, e.shape[0]), _shown(e))
            values.append(e)
        ref = None
        if reference is not None:
            e = np.asarray(reference, dtype=float)
            ref = (_times(t, e.shape[0]), _shown(e))
            values.append(e)
        _curves(ax, series, ref, featured)
        log = _log_scale(ax, log, np.concatenate(values) if values else [])
        ax.set_xlabel(_label("time $t$", u["t"]))
        ax.set_ylabel(_label("energy $H$", u["H"], log))
        ax.set_title(title or "Energy")
        _legend(ax, legend_ax, size, energies, featured)
        return _finish(_style(ax, size), path)


def frequency_response(linear, simulated=(), *, output=0, input=0, units=None, size="column",
                       ax=None, path=None, title=None):
    """The Bode plot of a driven model: the magnitude and phase of q_output per unit of
    u_input against the angular frequency, for the map linearised at its equilibrium
    (`linear`, the dict of Model.frequency_response(omega, h)) with its modes marked, and for
    each dict of `simulated` (Model.frequency_response(omega, h, amplitude=a)) the nonlinear
    response at that input amplitude (points where it did not settle are left out). `ax`: a
    pair of Axes (magnitude, phase) to draw into, the legend then inside the first."""
    omega = np.asarray(linear["omega"], dtype=float)
    g = np.asarray(linear["response"])
    if g.ndim != 3 or g.shape[0] != omega.size:
        raise ValueError("linear: expected the dict of Model.frequency_response(omega, h)")
    if not (0 <= output < g.shape[1] and 0 <= input < g.shape[2]):
        raise ValueError(f"output, input: expected 0 <= output < {g.shape[1]} and "
                         f"0 <= input < {g.shape[2]}")
    u = _units(units)
    with _rc(size):
        if ax is not None:
            if len(ax) != 2:
                raise ValueError("ax: expected a pair of Axes (magnitude, phase)")
            (mag_ax, phase_ax), legend_ax = ax, None
        else:
            fig, (mag_ax, phase_ax), legend_ax = _figure(size, 2, aspect=0.45,
                                                         entries=1 + len(simulated))
        lin = g[:, output, input]
        mag_ax.loglog(omega, np.abs(lin), color="black", lw=1.4, label="linearised")
        phase_ax.semilogx(omega, np.degrees(np.unwrap(np.angle(lin))), color="black", lw=1.4)
        for k, sim in enumerate(simulated):
            if sim.get("input_index", 0) != input:
                continue
            r = np.asarray(sim["response"])[:, output]
            ok = np.asarray(sim.get("settled", np.ones(r.size, bool)), dtype=bool)
            w = np.asarray(sim["omega"], dtype=float)
            label = f"amplitude {sim['amplitude']:.3g}"
            mag_ax.loglog(w[ok], np.abs(r[ok]), "o", ms=3, label=label, color=f"C{k}")
            phase_ax.semilogx(w[ok], np.degrees(np.angle(r[ok])), "o", ms=3, color=f"C{k}")
        for wn, zeta in linear.get("modes", []):
            for a in (mag_ax, phase_ax):
                a.axvline(wn, color="0.5", ls=":", lw=1.0)
            mag_ax.annotate(f"ω {wn:.3g}, ζ {zeta:.2g}", (wn, 1.0), xycoords=("data", "axes fraction"),
                            xytext=(2, -2), textcoords="offset points", va="top",
                            fontsize=_preset(size)[2]["small"], color="0.35")
        mag_ax.set_ylabel(_label(f"|q{output + 1} / u{input + 1}|"))
        phase_ax.set_ylabel("phase (degrees)")
        phase_ax.set_xlabel(_label("angular frequency", f"rad/{u['t']}" if u["t"] else ""))
        mag_ax.set_title(title or "Frequency response")
        handles, labels = mag_ax.get_legend_handles_labels()
        _put_legend(legend_ax or mag_ax, handles, labels, size, inside=legend_ax is None)
        _style(mag_ax, size)
        return _finish(_style(phase_ax, size), path)


def _positions_reference(reference, d):
    """The reference as (n+1, 2d) states and whether it holds positions alone: a (n+1, d)
    array of q columns (d from the predictions), or states whose momenta are all NaN."""
    r = np.asarray(reference, dtype=float)
    if r.ndim == 2 and d is not None and r.shape[1] == d and r.shape[1] != 2 * d:
        return np.hstack([r, np.full_like(r, np.nan)]), True
    r = _states("reference", r)
    half = r.shape[1] // 2
    return r, bool(r.shape[0]) and bool(np.all(np.isnan(r[:, half:])))


def rollout_figure(t, predictions, reference, *, energies=None, energy_ref=None, coord=0,
                   highlight=None, units=None, size="page", ncols=None, path=None, title=None,
                   caption=None):
    """The paper's rollout figure: phase portrait (q_i, p_i), q_i(t), accumulated error and,
    when `energies` ({label: (n+1,)}) is given, energy, with one legend for all panels.

    reference: states (n+1, 2d), or positions alone: (n+1, d) q columns, or states whose
    momenta are all NaN (a record without momenta). Then the phase portrait is left out and
    the accumulated error compares the positions only.

    title: a heading above the panels. caption: a sentence set below the figure, in the text's
    size and weight, as a paper's caption ("Table 2, S1: rollouts from the first test
    trajectory.").

    The panels wrap onto rows of `ncols` (default: four in one row for size="page", two
    per row for "column"); the legend takes a free cell of the grid or a row below it."""
    preds = _predictions(predictions)
    featured = _featured(preds, highlight)
    d = next(iter(preds.values())).shape[1] // 2 if preds else None
    reference, positions_only = _positions_reference(reference, d)
    panels = (4 if energies is not None else 3) - positions_only
    if ncols is None:
        ncols = 2 if _preset(size)[0] < 5.0 else 4
    width, _, p = _preset(size)
    caption_h = 0.0
    if caption:  # about half an em per character, 1.35 lines of the small font each
        per_line = max(20, int(width * 72.0 / (0.5 * p["small"])))
        caption_h = math.ceil(len(caption) / per_line) * p["small"] * 1.35 / 72.0 + 0.04
    with _rc(size):
        fig, axes, legend_ax = _figure(size, panels, ncols=ncols, aspect=0.9,
                                       entries=len(preds) + 1, caption_h=caption_h)
        common = {"highlight": featured if featured is not None else False, "units": units,
                  "size": size}
        if positions_only:
            axes = [None] + axes
            half = reference.shape[1] // 2
            # The error of the positions: the momenta set to zero on both sides.
            zero = {k: np.hstack([z[:, :half], np.zeros_like(z[:, half:])])
                    for k, z in preds.items()}
            error_ref = np.hstack([reference[:, :half], np.zeros_like(reference[:, half:])])
            trajectory(t, preds, reference, coord=coord, ax=axes[1], **common)
            accumulated_error(t, zero, error_ref, ax=axes[2], **common)
            axes[2].set_title("Accumulated error (positions)")
        else:
            phase_portrait(preds, reference, coord=coord, ax=axes[0], **common)
            trajectory(t, preds, reference, coord=coord, ax=axes[1], **common)
            accumulated_error(t, preds, reference, ax=axes[2], **common)
        if energies is not None:
            energy(t, energies, energy_ref, ax=axes[3],
                   **{**common, "highlight": featured if featured in energies else False})
            axes[3].set_title("Energy $H$")
        axes[1].set_title(f"$q_{{{coord + 1}}}(t)$")
        # One legend for the figure: per-panel legends would cover the curves. The q_i(t) panel
        # has every entry (the reference included).
        items = _legend_order(_entries(axes[1], preds), featured)
        for ax in axes:
            if ax is not None and ax.get_legend() is not None:
                ax.get_legend().remove()
        _put_legend(legend_ax, [h for _, h in items], [lab for lab, _ in items], size,
                    inside=False)
        if title:
            fig.suptitle(title)
        if caption:
            fig.caption_ax.text(0.0, 1.0, caption, ha="left", va="top", wrap=True,
                                fontsize=p["small"], transform=fig.caption_ax.transAxes)
        return _finish(fig, path)


def fit_figure(out_dir, data=None, path=None, *, model=None, size="page"):
    """The figure of a `csympnet fit` output directory (`fit` draws it as OUT/fit.png and
    OUT/fit.pdf): each dof's positions, record against the model's free run over the record's
    own sample times, from its first state (or, for positions alone, from the state fitted to
    the first window of positions); the residuals; the amplitude per half-cycle beside
    A0 exp(-gamma_hat t / 2) (gamma_hat is the energy's decay rate, so amplitudes decay at
    gamma_hat / 2); the modes with their intervals. Up to three dofs one panel each, then a
    summary of every dof's free-run error; of several trajectories the longest.

    data: the record (default: report.json's data file, read with its --columns map);
    model: a loaded Model (default: out_dir's model.json); path: save as PATH.png and
    PATH.pdf. Needs the compiled module for the model's rollouts (this module alone does
    not). Returns the Figure."""
    from csympnet._fit_record import read_fit  # the package: the rollouts are the library's

    run = read_fit(out_dir, data, model)
    fig = _fit_panels(run.report, run.data, run.rec, run.start, run.z, run.which, size,
                      response=run.response)
    if path is not None:
        _save_atomic(fig, path)
    return fig


# The fit figure's record points; dofs drawn one panel each, beyond them a summary panel.
_FIT_RECORD = {"color": "black", "lw": 0.0, "marker": ".", "markersize": 2.0, "zorder": 3}
_FIT_DOF_PANELS = 3




def _envelope(t, q_record, q_model):
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


def _fit_interval(iv, fmt="{:#.4g}"):
    return f" [{fmt.format(iv[0])}, {fmt.format(iv[1])}]" if iv else ""


def _fit_time_unit(report):
    unit = report.get("time_unit")
    return unit.get("unit") if isinstance(unit, dict) and unit.get("unit") else ""


def _fit_heading(report, data, which):
    per = _fit_time_unit(report) or "time unit"
    name = os.path.basename(data)
    g = report.get("gamma_hat")
    if report.get("identified"):
        lo, hi = report.get("gamma_ci_low"), report.get("gamma_ci_high")
        level = 100 * float(report.get("gamma_ci_level") or 0.95)
        text = (f"{name}: $\\hat\\gamma$ = {g:.4g}{_fit_interval((lo, hi) if lo is not None else None)}"
                f" per {per} ({level:g}% interval)")
    else:
        verdict = "model rejected" if report.get("verdict") == "model rejected" else "not identified"
        text = f"{name}: $\\gamma$ {verdict}" + (f" (estimate {g:.4g} per {per})" if g is not None else "")
    return text + (f"\n{which}" if which else "")


def _fit_modes_text(report, width=100):
    """The lines of the text panel: γ̂, the verdict and its reasons, the modes."""
    per = _fit_time_unit(report) or "time unit"
    lines = []
    g = report.get("gamma_hat")
    if g is not None:
        iv = ((report.get("gamma_ci_low"), report.get("gamma_ci_high"))
              if report.get("identified") and report.get("gamma_ci_low") is not None else None)
        lines.append(f"damping rate γ̂ = {g:.4g}{_fit_interval(iv)} per {per}: energy ∝ exp(−γ̂t), "
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
                     f"{_fit_interval(m.get('angular_frequency_interval'))}, "
                     f"damping ratio ζ = {m['damping_ratio']:#.4g}"
                     f"{_fit_interval(m.get('damping_ratio_interval'))}")
    if modes.get("note"):
        lines += textwrap.wrap(modes["note"], width)
    if not modes.get("list") and not modes.get("note"):
        lines.append("no oscillating mode")
    return lines


def _fit_panels(report, data, rec, start, z, which, size, response=None):
    d = rec.q.shape[1]
    shown = min(d, _FIT_DOF_PANELS)
    t, ts = rec.t, rec.t[start:]
    qhat = z[:, :d]
    unit = _fit_time_unit(report)
    tlabel = f"time ({unit})" if unit else "time (unit of the data)"
    rows = shown + 1 + (d > shown)
    width, _, preset = _preset(size)
    lines = _fit_modes_text(report, width=int(0.9 * width * 72.0 / (0.6 * preset["small"])))
    text_h = len(lines) * preset["small"] * 1.45 / 72.0 + 0.15
    with _rc(size):
        fig = Figure(figsize=(width, 1.9 * rows + text_h + 0.5), layout="constrained")
        FigureCanvasAgg(fig)
        gs = fig.add_gridspec(rows + 1, 2, width_ratios=[1.6, 1.0],
                              height_ratios=[1.9] * rows + [text_h])
        for i in range(shown):
            ax = fig.add_subplot(gs[i, 0])
            ax.plot(t, rec.q[:, i], label="record", **_FIT_RECORD)
            ax.plot(ts, _shown(qhat[:, i]), color=FEATURED_COLOR, lw=1.0,
                    label=("free run from the first state" if start == 0 else
                           f"free run from the state fitted\nto the first {start + 1} positions"
                           + (", fed the inputs" if response is not None else "")),
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
            res.plot(ts, _shown(r), color="0.25", lw=0.6)
            res.axhline(0.0, color="0.6", lw=0.5)
            res.set_title("residual, record − free run")
            res.set_ylabel(rec.names[i])
            for a in (ax, res):
                a.set_xlabel(tlabel)
                _style(a, size)
        row = shown
        if d > shown:
            ax = fig.add_subplot(gs[row, :])
            with np.errstate(invalid="ignore", over="ignore"):
                err = np.sqrt(np.mean((rec.q[start:] - qhat) ** 2, axis=0))
                spread = np.std(rec.q[start:], axis=0)
                rel = np.where(spread > 0, err / np.where(spread > 0, spread, 1.0), np.nan)
            ax.bar(np.arange(d), _shown(rel), color=FEATURED_COLOR)
            ax.set_xticks(np.arange(d), rec.names, rotation=45 if d > 6 else 0,
                          fontsize=preset["small"])
            ax.set_ylabel("rms error / spread")
            ax.set_title(f"free-run error of every dof (the first {shown} drawn above)")
            _style(ax, size)
            ax.grid(False, axis="x")
            row += 1
        if response is not None:  # a driven record: no free decay to draw an envelope of
            _response_panel(fig.add_subplot(gs[row, :]), response, rec.names, size,
                            _fit_time_unit(report))
        else:
            _envelope_panel(fig.add_subplot(gs[row, :]), report, rec, start, qhat, tlabel, size)
        text = fig.add_subplot(gs[row + 1, :])
        text.axis("off")
        text.text(0.0, 1.0, "\n".join(lines), ha="left", va="top", fontsize=preset["small"],
                  transform=text.transAxes, in_layout=False)
        fig.suptitle(_fit_heading(report, data, which))
    return fig


def _response_panel(ax, response, names, size, unit):
    """A driven model's linearised frequency response, |q_i / u_j| for every pair, with its
    modes marked (the magnitude panel of frequency_response)."""
    w = np.asarray(response["omega"], dtype=float)
    g = np.asarray(response["response"])
    for i in range(g.shape[1]):
        for j in range(g.shape[2]):
            ax.loglog(w, np.abs(g[:, i, j]), lw=1.2, label=f"{names[i]} / u{j + 1}",
                      color=FEATURED_COLOR if g.shape[1] * g.shape[2] == 1 else f"C{i + j}")
    for wn, _ in response.get("modes", []):
        ax.axvline(wn, color="0.5", ls=":", lw=0.8)
    ax.set_xlabel(f"angular frequency (rad/{unit})" if unit else "angular frequency (rad per time unit)")
    ax.set_ylabel("|q / u|")
    ax.set_title("frequency response of the fitted map, linearised (dotted: its modes)")
    if g.shape[1] * g.shape[2] > 1:
        ax.legend(loc="best", fontsize=_preset(size)[2]["small"], framealpha=0.85)
    _style(ax, size)


def _window_rms(t, q_record, q_model, period):
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
        tk, rec_peaks, mod_peaks = _window_rms(ts, rec.q[start:], qhat, period)
        ax.set_title(f"rms amplitude of q1..q{d} over windows of one period of the slowest mode")
        ylabel = "rms ‖q − centre‖\n(log scale)"
    else:
        finite = np.isfinite(qhat).all(axis=1)
        spread = np.std(qhat[finite], axis=0) if finite.any() else np.zeros(d)
        i = int(np.argmax(spread))
        tk, rec_peaks, mod_peaks, centre = _envelope(ts, rec.q[start:, i], qhat[:, i])
        ax.set_title(f"amplitude of {rec.names[i]} per half-cycle")
        sign = "−" if centre >= 0 else "+"
        ylabel = f"|{rec.names[i]} {sign} {abs(centre):.3g}|\n(log scale)"
    ax.set_xlabel(tlabel)
    if tk.size < 2:
        ax.text(0.5, 0.5, "the free run completes fewer than two half-cycles: no envelope",
                ha="center", va="center", transform=ax.transAxes, in_layout=False)
        ax.set_yticks([])
        _style(ax, size)
        return
    ax.plot(tk, rec_peaks, "o", color="black", ms=2.5, label="record", zorder=3)
    ax.plot(tk, mod_peaks, "-", color=FEATURED_COLOR, lw=1.0, label="free run", zorder=4)
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
    ax.legend(loc="best", fontsize=_preset(size)[2]["small"], framealpha=0.85)
    _style(ax, size)


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
    with rc_context(_TRUETYPE):
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


def summarize(samples):
    """(median, 25th percentile, 75th percentile) of a 1-D sample (e.g. one value per seed)."""
    a = np.asarray(samples, dtype=float).ravel()
    if a.size == 0:
        raise ValueError("samples: expected at least one value")
    with np.errstate(invalid="ignore"):
        q25, med, q75 = np.percentile(a, [25, 50, 75])
    return float(med), float(q25), float(q75)


def bars(groups, series, *, ylabel, xlabel=None, log=None, ylim=None, reference=None,
         reference_label=None, highlight=None, size="column", ax=None, path=None, title=None):
    """Grouped bars at the median with interquartile error bars (25th to 75th percentile).

    groups: labels of the x groups (e.g. noise levels).
    series: {label: [samples of group 0, samples of group 1, ...]}, one 1-D sample per group
        (e.g. the values over seeds).
    log: log scale (None: when the medians and quartiles span decades); the y label then says
        "log scale".
    ylim: (low, high) display range; bars beyond it are cut at the edge and marked with ▲/▼.
        This changes the display only, not the statistics.
    reference: a value drawn as a dashed horizontal line (label `reference_label`).
    highlight: the featured series (default "csympnet" when present): first in each group, in
        the featured colour with a dark edge; the others lighter.
    """
    if not isinstance(series, dict) or not series:
        raise TypeError("series: expected a non-empty dict {label: [samples per group]}")
    groups = [str(g) for g in groups]
    stats = {}
    for label, per_group in series.items():
        if len(per_group) != len(groups):
            raise ValueError(f"series[{label!r}]: has {len(per_group)} groups, expected {len(groups)}")
        stats[label] = np.array([summarize(s) for s in per_group])  # (G, 3): median, q25, q75
    featured = _featured(stats, highlight)
    if featured is not None:  # first in each group, next to the reference line's legend entry
        stats = {featured: stats[featured], **{k: v for k, v in stats.items() if k != featured}}
    styles = _styles(stats, featured)
    with _rc(size):
        fig, ax, legend_ax = _new_axes(ax, size, 0.62, len(stats) + (reference is not None))
        log = _log_scale(ax, log, np.concatenate([s.ravel() for s in stats.values()]))
        x = np.arange(len(groups))
        width = 0.8 / len(stats)
        for i, (label, s) in enumerate(stats.items()):
            pos = x - 0.4 + width * (i + 0.5)
            med, lo, hi = s[:, 0], s[:, 1], s[:, 2]
            shown = np.where(np.isfinite(med), med, np.nan)
            strong = label == featured
            ax.bar(pos, shown, width * 0.9, color=styles[label]["color"], label=_name(label),
                   alpha=1.0 if strong else 0.7, zorder=3 if strong else 2,
                   edgecolor="black" if strong else "none", linewidth=0.6 if strong else 0.0)
            err = np.vstack([np.clip(med - lo, 0, None), np.clip(hi - med, 0, None)])
            ax.errorbar(pos, shown, yerr=np.where(np.isfinite(err), err, 0.0), fmt="none",
                        ecolor="black", elinewidth=0.8, capsize=1.5 if width < 0.15 else 2.5,
                        zorder=4)
        if reference is not None:
            ax.axhline(reference, label="reference",
                       **{**_REFERENCE, "lw": 1.0})
        if ylim is not None:
            ax.set_ylim(*ylim)
            _mark_clipped(ax, x, width, stats, styles, ylim)
        ax.set_xticks(x, groups)
        if xlabel:
            ax.set_xlabel(xlabel)
        ax.set_ylabel(_label(ylabel, "", log))
        ax.grid(False, axis="x")
        if title:
            ax.set_title(title)
        items = _legend_order(_entries(ax, stats), featured)
        shown_labels = [(reference_label or "reference") if lab == "reference" else lab
                        for lab, _ in items]
        _put_legend(ax if legend_ax is None else legend_ax, [h for _, h in items], shown_labels,
                    size, inside=legend_ax is None)
        _style(ax, size)
        ax.grid(False, axis="x")
        return _finish(fig, path)


def _mark_clipped(ax, x, width, stats, styles, ylim):
    lo_lim, hi_lim = ylim
    for i, (label, s) in enumerate(stats.items()):
        pos = x - 0.4 + width * (i + 0.5)
        for j, (med, _, hi) in enumerate(s):
            if not np.isfinite(med) or hi > hi_lim:
                ax.annotate("▲", (pos[j], hi_lim), ha="center", va="top", fontsize=6,
                            color=styles[label]["color"], annotation_clip=False, zorder=5)
            elif med < lo_lim:
                ax.annotate("▼", (pos[j], lo_lim), ha="center", va="bottom", fontsize=6,
                            color=styles[label]["color"], annotation_clip=False, zorder=5)


def noise_labels(noise_levels):
    """Tick labels for noise levels: 0 → "0", 1e-4 → "1e-4"."""
    return ["0" if s == 0 else f"{s:.0e}".replace("e-0", "e-") for s in map(float, noise_levels)]


_noise_labels = noise_labels  # the name experiments/figures.py first used


def error_vs_noise(noise_levels, errors, *, ylim=None, highlight=None, units=None, size="column",
                   ax=None, path=None, title=None):
    """L2 rollout error against noise level σ: bars at the median over seeds with IQR error bars.
    errors: {model: [errors over seeds at each σ]}."""
    u = _units(units)
    unit = f" ({u['E']})" if u["E"] else ""
    return bars(noise_labels(noise_levels), errors, ylabel="$L^2$ rollout error" + unit,
                xlabel="relative noise level $\\sigma$", ylim=ylim, highlight=highlight,
                size=size, ax=ax, path=path, title=title or "Rollout error under noise")


def lambda_vs_noise(noise_levels, lambdas, lambda_star, *, ylim=None, highlight=None,
                    size="column", ax=None, path=None, title=None):
    """Learned conformal factor λ̂ against noise level σ, with λ* dashed: bars at the median over
    seeds with IQR error bars. lambdas: {model: [λ̂ over seeds at each σ]}. The default range is
    centred on λ* and wide enough for every quartile (pass ylim to clip outliers)."""
    if ylim is None:
        ends = np.concatenate([np.ravel([summarize(s) for s in v]) for v in lambdas.values()])
        ends = ends[np.isfinite(ends)]
        w = max(1.2 * np.max(np.abs(ends - lambda_star)) if ends.size else 0.0, 1e-4)
        ylim = (lambda_star - w, lambda_star + w)
    return bars(noise_labels(noise_levels), lambdas,
                ylabel="learned factor $\\hat\\lambda$ (dimensionless)",
                xlabel="relative noise level $\\sigma$", log=False, ylim=ylim,
                reference=lambda_star, reference_label="$\\lambda^*$", highlight=highlight,
                size=size, ax=ax, path=path, title=title or "Learned conformal factor under noise")
