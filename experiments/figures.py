#!/usr/bin/python3
"""Figures of a reproduction: `figures.py DIR [--size auto|column|page]` reads DIR/summary.json
and DIR/runs/*.json (written by `csympnet reproduce`) and writes PNG and PDF files to
DIR/figures/.

--size: "column" (3.5 in wide) or "page" (7.2 in wide) for every figure; "auto" (the default)
draws the rollout figures at page width and the bar charts at column width. CSympNet-ID is the
featured model of every figure (drawn on top, in red); PDFs embed TrueType fonts.

The drawing code is csympnet.plot (python/csympnet/plot.py), loaded by file path so that the
figures need only NumPy and matplotlib, not the compiled module.

  SUITE-PRESET-rollout   table suites with trajectories (table2, table5, reference): phase
                         portrait (q1, p1), q1(t), accumulated error, energy; all models
  noise-PRESET-l2        L2 error against sigma, median and IQR over seeds
  noise-PRESET-lambda    learned factor lambda_hat against sigma, lambda* dashed
  noise-PRESET-gamma     |gamma_hat - gamma| against sigma, models with a gamma_hat
  samples-PRESET-l2      L2 error against N_train
  hsweep-PRESET-sigmaS   L2 error against h_test, trained at h = 0.1 (s1: U[0.05, 0.15])
"""

import argparse
import importlib.util
import json
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
PLOT_PATH = os.path.join(HERE, os.pardir, "python", "csympnet", "plot.py")


def load_plot():
    spec = importlib.util.spec_from_file_location("csympnet_plot", PLOT_PATH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


ORDER = ["csympnet", "sympnet", "map", "ode", "dhnn", "dhnn2", "phnn", "phnn2"]


def ordered(by_model):
    """Items of a {model: ...} dict in the paper's model order."""
    rank = {m: i for i, m in enumerate(ORDER)}
    return sorted(by_model.items(), key=lambda kv: rank.get(kv[0], len(ORDER)))


def values(stat):
    """Per-seed values of a summary statistic; NaN where a run blew up (stored as null)."""
    if stat is None:
        return [np.nan]
    return [np.nan if v is None else v for v in stat["values"]]


def records_by_key(out):
    runs = os.path.join(out, "runs")
    by_key = {}
    for name in sorted(os.listdir(runs)):
        if name.endswith(".json"):
            with open(os.path.join(runs, name)) as f:
                rec = json.load(f)
            by_key[rec["key"]] = rec
    return by_key


def rollout_figures(plot, summary, records, suite, figdir, size):
    for preset, by_model in summary[suite].items():
        if not isinstance(by_model, dict) or preset in ("title", "kind", "vary"):
            continue
        preds, energies, ref, e_ref, t = {}, {}, None, None, None
        for model, entry in ordered(by_model):
            rec = records.get(entry.get("key"))
            if rec is None or rec.get("status") != "ok":
                continue
            tr = rec["trajectory"]
            t, ref, e_ref = np.array(tr["t"]), np.array(tr["reference"]), np.array(tr["energy_ref"])
            preds[model] = np.array(tr["prediction"], dtype=float)
            energies[model] = np.array(tr["energy_pred"], dtype=float)
        if not preds:
            continue
        caption = (f"{summary[suite]['title'].split(':')[0]}, preset {preset}: every model's "
                   "rollout from the first test trajectory against the reference solution "
                   "(dashed).")
        plot.rollout_figure(t, preds, ref, energies=energies, energy_ref=e_ref, size=size,
                            path=os.path.join(figdir, f"{suite}-{preset}-rollout"),
                            caption=caption)


def cells_by(summary, suite, preset, key, sigma=None):
    """{model: ([x values], [per-seed samples per x])} for a grid suite."""
    out = {}
    for model, cells in ordered(summary[suite][preset]):
        chosen = [c for c in cells if sigma is None or c["sigma"] == sigma]
        chosen.sort(key=lambda c: c[key])
        out[model] = ([c[key] for c in chosen], chosen)
    return out


def grid_figures(plot, summary, figdir, size):
    suites = summary["suites"]
    presets = lambda s: [p for p in summary[s] if p not in ("title", "kind", "vary")]
    if "noise" in suites:
        for preset in presets("noise"):
            cells = cells_by(summary, "noise", preset, "sigma")
            sigmas = next(iter(cells.values()))[0]
            l2 = {m: [values(c["l2_error"]) for c in cs] for m, (_, cs) in cells.items()}
            plot.error_vs_noise(sigmas, l2, size=size,
                                path=os.path.join(figdir, f"noise-{preset}-l2"),
                                title=f"{preset}: rollout error under noise")
            lam = {m: [values(c["lambda_hat"]) for c in cs] for m, (_, cs) in cells.items()}
            lam_star = next(iter(cells.values()))[1][0]["lambda_star"]
            plot.lambda_vs_noise(sigmas, lam, lam_star, size=size,
                                 path=os.path.join(figdir, f"noise-{preset}-lambda"),
                                 title=f"{preset}: learned factor under noise")
            gam = {m: [values(c["gamma_abs_err"]) for c in cs] for m, (_, cs) in cells.items()
                   if cs and cs[0]["gamma_abs_err"] is not None}
            if gam:
                plot.bars(plot.noise_labels(sigmas), gam,
                          ylabel="$|\\hat\\gamma-\\gamma|$ (a.u.)",
                          xlabel="relative noise level $\\sigma$", log=True, size=size,
                          path=os.path.join(figdir, f"noise-{preset}-gamma"),
                          title=f"{preset}: damping-rate error under noise")
    if "samples" in suites:
        for preset in presets("samples"):
            cells = cells_by(summary, "samples", preset, "n_train")
            sizes = next(iter(cells.values()))[0]
            l2 = {m: [values(c["l2_error"]) for c in cs] for m, (_, cs) in cells.items()}
            plot.bars([str(n) for n in sizes], l2, ylabel="$L^2$ rollout error (a.u.)",
                      xlabel="training pairs $N_{\\mathrm{train}}$", size=size,
                      path=os.path.join(figdir, f"samples-{preset}-l2"),
                      title=f"{preset}: sample efficiency")
    if "hsweep" in suites:
        for preset in presets("hsweep"):
            sigmas = sorted({c["sigma"] for cs in summary["hsweep"][preset].values() for c in cs})
            for sigma in sigmas:
                cells = cells_by(summary, "hsweep", preset, "h_test", sigma=sigma)
                hs = next(iter(cells.values()))[0]
                l2 = {m: [values(c["l2_error"]) for c in cs] for m, (_, cs) in cells.items()}
                plot.bars([f"{h:g}" for h in hs], l2, ylabel="$L^2$ rollout error (a.u.)",
                          xlabel="test step $h_{\\mathrm{test}}$ (a.u.)", size=size,
                          path=os.path.join(figdir, f"hsweep-{preset}-sigma{sigma:g}"),
                          title=f"{preset}: test-step sweep, $\\sigma$ = {sigma:g}")


def main(argv):
    parser = argparse.ArgumentParser(
        prog="figures.py", description="Draws the figures of a csympnet reproduce directory.")
    parser.add_argument("dir", help="the --out directory of csympnet reproduce")
    parser.add_argument("--size", choices=["auto", "column", "page"], default="auto",
                        help="figure width: column (3.5 in), page (7.2 in), or auto (rollout "
                             "figures page wide, bar charts column wide; the default)")
    args = parser.parse_args(argv[1:])
    out = args.dir
    rollout_size = "page" if args.size == "auto" else args.size
    bar_size = "column" if args.size == "auto" else args.size
    summary_path = os.path.join(out, "summary.json")
    if not os.path.exists(summary_path):
        sys.exit(f"figures.py: {summary_path} not found; run csympnet reproduce first")
    with open(summary_path) as f:
        summary = json.load(f)
    plot = load_plot()
    figdir = os.path.join(out, "figures")
    os.makedirs(figdir, exist_ok=True)
    records = records_by_key(out)
    for suite in summary["suites"]:
        if summary[suite]["kind"] == "table" and suite in ("table2", "table5", "reference"):
            rollout_figures(plot, summary, records, suite, figdir, rollout_size)
    grid_figures(plot, summary, figdir, bar_size)
    print(f"figures.py: wrote {len(os.listdir(figdir))} files to {figdir}")


if __name__ == "__main__":
    main(sys.argv)
