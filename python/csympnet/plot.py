"""The paper's figure types from plain NumPy arrays and dicts.

Depends on NumPy and matplotlib only (not on the compiled csympnet module), so a script can load
this file by path. Figures are built on matplotlib's Agg canvas without pyplot, so importing it
never changes the backend of the calling program.

Conventions: a trajectory of states is an array (n+1, 2d) whose columns are q1..qd, p1..pd;
`predictions` is a dict {label: states}; model type names ("csympnet", "map", ...) are shown
with the paper's names. Every function takes `ax=` (draw into an existing Axes) and `path=`
(save the figure as PNG and PDF, see `save`) and returns the matplotlib Figure.

Functions (signatures in docs/python.md): phase_portrait, trajectory, accumulated_error, energy,
rollout_figure, accumulated_errors, bars, error_vs_noise, lambda_vs_noise, noise_labels,
summarize, save.
"""

import os

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

#: The paper's names of the model types.
MODEL_NAMES = {
    "csympnet": "CSympNet-ID", "sympnet": "SympNet", "map": "MapBaseline", "ode": "ODEBaseline",
    "dhnn": "DHNN", "dhnn2": "DHNN2", "phnn": "pHNN", "phnn2": "pHNN2",
}
_COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
           "#7f7f7f", "#bcbd22", "#17becf"]
_FONT = {"axes.titlesize": 11, "axes.labelsize": 10, "legend.fontsize": 8,
         "xtick.labelsize": 9, "ytick.labelsize": 9}


def _name(label):
    return MODEL_NAMES.get(label, str(label))


def _color(i):
    return _COLORS[i % len(_COLORS)]


def _new_axes(ax, figsize=(4.8, 3.6)):
    """(figure, axes): the given axes and its figure, or a new one-panel figure."""
    if ax is not None:
        return ax.figure, ax
    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot()


def _style(ax, fig):
    ax.title.set_fontsize(_FONT["axes.titlesize"])
    ax.xaxis.label.set_fontsize(_FONT["axes.labelsize"])
    ax.yaxis.label.set_fontsize(_FONT["axes.labelsize"])
    ax.tick_params(labelsize=_FONT["xtick.labelsize"])
    ax.grid(True, which="major", alpha=0.3)
    return fig


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


def save(fig, path, dpi=200):
    """Writes `fig` as PATH.png and PATH.pdf (a .png/.pdf suffix on `path` is dropped), creating
    the directory. Returns the two paths written."""
    base, ext = os.path.splitext(os.fspath(path))
    if ext.lower() not in (".png", ".pdf"):
        base = os.fspath(path)
    folder = os.path.dirname(base)
    if folder:
        os.makedirs(folder, exist_ok=True)
    written = []
    for suffix in (".png", ".pdf"):
        fig.savefig(base + suffix, dpi=dpi)
        written.append(base + suffix)
    return written


def _finish(fig, path):
    if path is not None:
        save(fig, path)
    return fig


def phase_portrait(predictions, reference=None, *, coord=0, ax=None, path=None, title=None):
    """Phase portrait (q_i, p_i) of coordinate i = coord + 1 (default q1, p1).

    predictions: {label: states (n+1, 2d)}; reference: states (n+1, 2d) or None.
    """
    preds = _predictions(predictions)
    fig, ax = _new_axes(ax, (4.0, 3.8))
    d = None
    if reference is not None:
        ref = _states("reference", reference)
        d = ref.shape[1] // 2
        ax.plot(_shown(ref[:, coord]), _shown(ref[:, d + coord]), "k--", lw=1.6, label="reference")
        ax.plot(ref[0, coord], ref[0, d + coord], "ko", ms=4)
    for i, (label, z) in enumerate(preds.items()):
        dz = z.shape[1] // 2
        ax.plot(_shown(z[:, coord]), _shown(z[:, dz + coord]), color=_color(i), lw=1.2,
                label=_name(label))
        d = dz
    ax.set_xlabel(f"$q_{{{coord + 1}}}$")
    ax.set_ylabel(f"$p_{{{coord + 1}}}$")
    ax.set_title(title or "Phase portrait")
    ax.legend(loc="best")
    return _finish(_style(ax, fig), path)


def trajectory(t, predictions, reference=None, *, coord=0, ax=None, path=None, title=None):
    """q_i(t) for coordinate i = coord + 1 (default q1). t: times (n+1,)."""
    preds = _predictions(predictions)
    fig, ax = _new_axes(ax)
    n = next(iter(preds.values())).shape[0] if preds else _states("reference", reference).shape[0]
    ts = _times(t, n)
    if reference is not None:
        ref = _states("reference", reference)
        ax.plot(ts, _shown(ref[:, coord]), "k--", lw=1.6, label="reference")
    for i, (label, z) in enumerate(preds.items()):
        ax.plot(_times(t, z.shape[0]), _shown(z[:, coord]), color=_color(i), lw=1.2,
                label=_name(label))
    ax.set_xlabel("$t$")
    ax.set_ylabel(f"$q_{{{coord + 1}}}(t)$")
    ax.set_title(title or f"Trajectory $q_{{{coord + 1}}}$")
    ax.legend(loc="best")
    return _finish(_style(ax, fig), path)


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


def accumulated_error(t, predictions, reference, *, log=None, ax=None, path=None, title=None):
    """Accumulated rollout error E(t) (see `accumulated_errors`); log scale when it spans
    decades (log=None), or as forced by log=True/False."""
    errs = accumulated_errors(t, predictions, reference)
    fig, ax = _new_axes(ax)
    ts = _times(t, _states("reference", reference).shape[0])
    for i, (label, e) in enumerate(errs.items()):
        ax.plot(ts[1:], _shown(e[1:]), color=_color(i), lw=1.2, label=_name(label))
    _log_scale(ax, log, np.concatenate([e[1:] for e in errs.values()]) if errs else [])
    ax.set_xlabel("$t$")
    ax.set_ylabel("accumulated $L^2$ error")
    ax.set_title(title or "Accumulated error")
    ax.legend(loc="best")
    return _finish(_style(ax, fig), path)


def energy(t, energies, reference=None, *, log=None, ax=None, path=None, title=None):
    """Energy H along rollouts. energies: {label: (n+1,)}; reference: (n+1,) or None."""
    if not isinstance(energies, dict):
        raise TypeError("energies: expected a dict {label: energy values (n+1,)}")
    fig, ax = _new_axes(ax)
    values = []
    if reference is not None:
        e = np.asarray(reference, dtype=float)
        ax.plot(_times(t, e.shape[0]), _shown(e), "k--", lw=1.6, label="reference")
        values.append(e)
    for i, (label, e) in enumerate(energies.items()):
        e = np.asarray(e, dtype=float)
        ax.plot(_times(t, e.shape[0]), _shown(e), color=_color(i), lw=1.2, label=_name(label))
        values.append(e)
    _log_scale(ax, log, np.concatenate(values) if values else [])
    ax.set_xlabel("$t$")
    ax.set_ylabel("energy $H$")
    ax.set_title(title or "Energy")
    ax.legend(loc="best")
    return _finish(_style(ax, fig), path)


def rollout_figure(t, predictions, reference, *, energies=None, energy_ref=None, coord=0,
                   path=None, title=None):
    """The paper's rollout figure: phase portrait (q1, p1), q1(t), accumulated error and, when
    `energies` ({label: (n+1,)}) is given, energy — one row of panels."""
    panels = 4 if energies is not None else 3
    fig = Figure(figsize=(3.9 * panels + 1.6, 3.5), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, panels)
    phase_portrait(predictions, reference, coord=coord, ax=axes[0])
    trajectory(t, predictions, reference, coord=coord, ax=axes[1])
    accumulated_error(t, predictions, reference, ax=axes[2])
    if energies is not None:
        energy(t, energies, energy_ref, ax=axes[3])
    # One legend for the row, outside the last panel: with many models, per-panel legends
    # would cover the curves. The q1(t) panel has every entry (reference included).
    handles, labels = axes[1].get_legend_handles_labels()
    for ax in axes:
        if ax.get_legend() is not None:
            ax.get_legend().remove()
    axes[-1].legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0),
                    borderaxespad=0.0)
    if title:
        fig.suptitle(title, fontsize=12)
    return _finish(fig, path)


def summarize(samples):
    """(median, 25th percentile, 75th percentile) of a 1-D sample (e.g. one value per seed)."""
    a = np.asarray(samples, dtype=float).ravel()
    if a.size == 0:
        raise ValueError("samples: expected at least one value")
    with np.errstate(invalid="ignore"):
        q25, med, q75 = np.percentile(a, [25, 50, 75])
    return float(med), float(q25), float(q75)


def bars(groups, series, *, ylabel, xlabel=None, log=None, ylim=None, reference=None,
         reference_label=None, ax=None, path=None, title=None):
    """Grouped bars at the median with interquartile error bars (25th to 75th percentile).

    groups: labels of the x groups (e.g. noise levels).
    series: {label: [samples of group 0, samples of group 1, ...]}, one 1-D sample per group
        (e.g. the values over seeds).
    log: log scale (None: when the medians and quartiles span decades).
    ylim: (low, high) display range; bars beyond it are cut at the edge and marked with ▲/▼.
        This changes the display only, not the statistics.
    reference: a value drawn as a dashed horizontal line (label `reference_label`).
    """
    if not isinstance(series, dict) or not series:
        raise TypeError("series: expected a non-empty dict {label: [samples per group]}")
    groups = [str(g) for g in groups]
    stats = {}
    for label, per_group in series.items():
        if len(per_group) != len(groups):
            raise ValueError(f"series[{label!r}]: has {len(per_group)} groups, expected {len(groups)}")
        stats[label] = np.array([summarize(s) for s in per_group])  # (G, 3): median, q25, q75
    fig, ax = _new_axes(ax, (max(4.8, 1.2 * len(groups) + 1.5) + 1.4, 3.6))
    log = _log_scale(ax, log, np.concatenate([s.ravel() for s in stats.values()]))
    x = np.arange(len(groups))
    width = 0.8 / len(stats)
    for i, (label, s) in enumerate(stats.items()):
        pos = x - 0.4 + width * (i + 0.5)
        med, lo, hi = s[:, 0], s[:, 1], s[:, 2]
        shown = np.where(np.isfinite(med), med, np.nan)
        ax.bar(pos, shown, width * 0.9, color=_color(i), label=_name(label), alpha=0.85)
        err = np.vstack([np.clip(med - lo, 0, None), np.clip(hi - med, 0, None)])
        ax.errorbar(pos, shown, yerr=np.where(np.isfinite(err), err, 0.0), fmt="none",
                    ecolor="black", elinewidth=1, capsize=3)
    if reference is not None:
        ax.axhline(reference, color="black", ls="--", lw=1.3, label=reference_label or "reference")
    if ylim is not None:
        ax.set_ylim(*ylim)
        _mark_clipped(ax, x, width, stats, ylim)
    ax.set_xticks(x, groups)
    if xlabel:
        ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    # Outside the axes, right of them: inside, with up to eight series, "best" still covered
    # bars (checked on the full reproduction's figures).
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    return _finish(_style(ax, fig), path)


def _mark_clipped(ax, x, width, stats, ylim):
    lo_lim, hi_lim = ylim
    for i, s in enumerate(stats.values()):
        pos = x - 0.4 + width * (i + 0.5)
        for j, (med, _, hi) in enumerate(s):
            if not np.isfinite(med) or hi > hi_lim:
                ax.annotate("▲", (pos[j], hi_lim), ha="center", va="top", fontsize=7,
                            color=_color(i), annotation_clip=False)
            elif med < lo_lim:
                ax.annotate("▼", (pos[j], lo_lim), ha="center", va="bottom", fontsize=7,
                            color=_color(i), annotation_clip=False)


def noise_labels(noise_levels):
    """Tick labels for noise levels: 0 → "0", 1e-4 → "1e-4"."""
    return ["0" if s == 0 else f"{s:.0e}".replace("e-0", "e-") for s in map(float, noise_levels)]


_noise_labels = noise_labels  # the name experiments/figures.py first used


def error_vs_noise(noise_levels, errors, *, ylim=None, ax=None, path=None, title=None):
    """L2 rollout error against noise level σ: bars at the median over seeds with IQR error bars.
    errors: {model: [errors over seeds at each σ]}."""
    return bars(noise_labels(noise_levels), errors, ylabel="$L^2$ rollout error",
                xlabel="noise level $\\sigma$", ylim=ylim, ax=ax, path=path,
                title=title or "Rollout error under noise")


def lambda_vs_noise(noise_levels, lambdas, lambda_star, *, ylim=None, ax=None, path=None,
                    title=None):
    """Learned conformal factor λ̂ against noise level σ, with λ* dashed: bars at the median over
    seeds with IQR error bars. lambdas: {model: [λ̂ over seeds at each σ]}. The default range is
    centred on λ* and wide enough for every quartile (pass ylim to clip outliers)."""
    if ylim is None:
        ends = np.concatenate([np.ravel([summarize(s) for s in v]) for v in lambdas.values()])
        ends = ends[np.isfinite(ends)]
        w = max(1.2 * np.max(np.abs(ends - lambda_star)) if ends.size else 0.0, 1e-4)
        ylim = (lambda_star - w, lambda_star + w)
    return bars(noise_labels(noise_levels), lambdas, ylabel="learned factor $\\hat\\lambda$",
                xlabel="noise level $\\sigma$", log=False, ylim=ylim,
                reference=lambda_star, reference_label="$\\lambda^*$", ax=ax, path=path,
                title=title or "Learned conformal factor under noise")
