"""csympnet.plot: every figure type renders to PNG and PDF, from plain arrays; the featured
model is drawn on top; size presets, TrueType fonts and units in the labels."""

import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("matplotlib")
from conftest import SOURCE_DIR  # noqa: E402
from csympnet import plot  # noqa: E402


def damped(t, gamma=0.1, scale=1.0):
    return scale * np.exp(-gamma * t / 2)[:, None] * np.c_[np.cos(t), -np.sin(t)]


T = np.linspace(0.0, 10.0, 51)
REF = damped(T)
PREDS = {"csympnet": REF + 1e-6 * np.sin(T)[:, None], "map": damped(T, gamma=0.02)}


def written(tmp_path, name):
    return [(tmp_path / f"{name}{ext}").stat().st_size > 1000 for ext in (".png", ".pdf")]


def legend_texts(fig):
    """The entries of the figure's legends, in order."""
    return [t.get_text() for ax in fig.axes if ax.get_legend() is not None
            for t in ax.get_legend().get_texts()]


def panels(fig):
    """The axes of a figure that draw data (not the one holding a figure's legend)."""
    return [ax for ax in fig.axes if ax.axison]


def pdf_fonts(path):
    """The /Subtype of every font object in a PDF file written by matplotlib (it writes font
    dictionaries uncompressed, one object each)."""
    fonts = []
    for obj in open(path, "rb").read().split(b"endobj"):
        if re.search(rb"/Type\s*/Font\b", obj):
            fonts.append(re.search(rb"/Subtype\s*/(\w+)", obj).group(1).decode())
    return fonts


def test_each_rollout_panel(tmp_path):
    fig = plot.phase_portrait(PREDS, REF, path=tmp_path / "phase")
    assert written(tmp_path, "phase") == [True, True]
    ax = fig.axes[0]
    assert ax.get_xlabel() == "$q_{1}$ (a.u.)" and ax.get_ylabel() == "$p_{1}$ (a.u.)"
    assert legend_texts(fig) == ["reference", "CSympNet-ID", "MapBaseline"]
    plot.trajectory(T, PREDS, REF, path=tmp_path / "traj")
    fig = plot.accumulated_error(T, PREDS, REF, path=tmp_path / "err")
    assert fig.axes[0].get_yscale() == "log"  # 1e-6 against 1e-1: decades
    fig = plot.energy(T, {k: 0.5 * np.sum(v ** 2, axis=1) for k, v in PREDS.items()},
                      0.5 * np.sum(REF ** 2, axis=1), path=tmp_path / "energy.png")
    assert fig.axes[0].get_yscale() == "linear"
    for name in ("traj", "err", "energy"):
        assert written(tmp_path, name) == [True, True]


def test_rollout_figure_has_four_panels(tmp_path):
    energies = {k: 0.5 * np.sum(v ** 2, axis=1) for k, v in PREDS.items()}
    fig = plot.rollout_figure(T, PREDS, REF, energies=energies, energy_ref=energies["csympnet"],
                              path=tmp_path / "sub" / "rollout", title="S1")
    assert len(panels(fig)) == 4 and written(tmp_path / "sub", "rollout") == [True, True]
    assert len(panels(plot.rollout_figure(T, PREDS, REF))) == 3


def test_accumulated_error_ends_at_the_l2_error():
    e = plot.accumulated_errors(T, PREDS, REF)["map"]
    diff = PREDS["map"] - REF
    assert e[0] == 0.0
    assert e[-1] == pytest.approx(np.sqrt(np.sum(diff[1:] ** 2 * 0.2)), rel=1e-12)
    assert np.all(np.diff(e) >= 0)


def test_summarize_is_median_and_quartiles():
    med, q25, q75 = plot.summarize([1.0, 2.0, 3.0, 4.0, 100.0])
    assert (med, q25, q75) == (3.0, 2.0, 4.0)
    with pytest.raises(ValueError, match="at least one"):
        plot.summarize([])


def test_bars_median_iqr_and_clipping(tmp_path):
    rng = np.random.default_rng(0)
    errors = {"csympnet": [rng.lognormal(-8, 0.2, 10) for _ in range(4)],
              "map": [rng.lognormal(3, 0.2, 10) for _ in range(4)]}
    fig = plot.error_vs_noise([0, 1e-4, 1e-3, 1e-2], errors, path=tmp_path / "noise")
    ax = fig.axes[0]
    assert ax.get_yscale() == "log" and written(tmp_path, "noise") == [True, True]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["0", "1e-4", "1e-3", "1e-2"]
    heights = sorted(p.get_height() for p in ax.patches)
    expected = sorted(plot.summarize(s)[0] for v in errors.values() for s in v)
    np.testing.assert_allclose(heights, expected, rtol=1e-12)
    clipped = plot.error_vs_noise([0, 1e-2], {k: v[:2] for k, v in errors.items()}, ylim=(1e-5, 1.0))
    assert sum(t.get_text() == "▲" for t in clipped.axes[0].texts) == 2  # the map bars


def test_lambda_vs_noise_marks_lambda_star(tmp_path):
    lam = {"csympnet": [0.99 + 1e-5 * np.arange(5)] * 3, "sympnet": [np.ones(5)] * 3}
    fig = plot.lambda_vs_noise([0, 1e-3, 1e-2], lam, 0.99, path=tmp_path / "lam")
    ax = fig.axes[0]
    dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    assert len(dashed) == 1 and np.allclose(dashed[0].get_ydata(), 0.99)
    lo, hi = ax.get_ylim()
    assert lo < 0.99 < hi and hi >= 1.0 and ax.get_yscale() == "linear"
    assert written(tmp_path, "lam") == [True, True]


def test_bad_plot_input():
    with pytest.raises(ValueError, match="reference: expected states of shape"):
        plot.phase_portrait(PREDS, REF[:, :1])
    with pytest.raises(ValueError, match="t: expected 51 times"):
        plot.trajectory(T[:-1], PREDS, REF)
    with pytest.raises(TypeError, match="predictions: expected a dict"):
        plot.accumulated_error(T, [REF], REF)
    with pytest.raises(ValueError, match=r"series\['a'\]: has 1 groups, expected 2"):
        plot.bars(["x", "y"], {"a": [[1.0]]}, ylabel="v")


def test_blown_up_rollout_still_draws(tmp_path):
    blown = REF.copy()
    blown[30:] = np.inf  # what a diverged rollout looks like (diagnostics: +inf from there on)
    energies = {"map": np.where(np.isfinite(blown[:, 0]), 1.0, np.inf)}
    fig = plot.rollout_figure(T, {"map": blown}, REF, energies=energies, path=tmp_path / "b")
    assert written(tmp_path, "b") == [True, True]
    for ax in fig.axes:
        assert np.all(np.isfinite(ax.get_ylim())) and np.all(np.isfinite(ax.get_xlim()))
    assert plot.noise_labels([0, 1e-4, 0.01]) == ["0", "1e-4", "1e-2"]


def test_pdfs_embed_truetype_not_type3(tmp_path):
    energies = {k: 0.5 * np.sum(v ** 2, axis=1) for k, v in PREDS.items()}
    fig = plot.rollout_figure(T, PREDS, REF, energies=energies, path=tmp_path / "roll")
    clipped = plot.error_vs_noise([0, 1e-2], {"csympnet": [[1e-6], [1e-5]], "map": [[1.0], [9.0]]},
                                  ylim=(1e-7, 1e-1), path=tmp_path / "bars")  # ▲ glyphs
    assert any(t.get_text() == "▲" for t in clipped.axes[0].texts)
    for name in ("roll", "bars"):
        fonts = pdf_fonts(tmp_path / f"{name}.pdf")
        assert "Type3" not in fonts, fonts
        assert "CIDFontType2" in fonts or "TrueType" in fonts, fonts
    # The check sees Type 3 fonts where they are: matplotlib's own default for the same figure.
    from matplotlib import rc_context
    with rc_context({"pdf.fonttype": 3}):
        fig.savefig(tmp_path / "type3.pdf")
    assert "Type3" in pdf_fonts(tmp_path / "type3.pdf")


def test_the_callers_rcparams_are_left_alone(tmp_path):
    import matplotlib
    before = dict(matplotlib.rcParams)
    plot.rollout_figure(T, PREDS, REF, size="column", path=tmp_path / "a")
    plot.error_vs_noise([0, 1e-3], {"csympnet": [[1.0], [2.0]]}, size="page", path=tmp_path / "b")
    after = dict(matplotlib.rcParams)
    assert {k: v for k, v in after.items() if before.get(k) != v} == {}


def test_featured_model_is_drawn_on_top_in_its_own_style():
    # pHNN2 lies on the reference and on CSympNet-ID: CSympNet-ID must still be seen.
    preds = {"phnn2": REF, "csympnet": REF, "map": damped(T, gamma=0.02)}
    fig = plot.trajectory(T, preds, REF)
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    ref, featured = lines["reference"], lines["CSympNet-ID"]
    others = [lines["pHNN2"], lines["MapBaseline"]]
    assert ref.get_linestyle() == "--" and ref.get_color() == "black"
    assert ref.get_zorder() > featured.get_zorder() > max(o.get_zorder() for o in others)
    assert featured.get_color() == plot.FEATURED_COLOR and featured.get_linestyle() == "-"
    assert featured.get_linewidth() > max(o.get_linewidth() for o in others)
    assert all(o.get_color() != plot.FEATURED_COLOR for o in others)
    assert legend_texts(fig) == ["reference", "CSympNet-ID", "pHNN2", "MapBaseline"]
    # Its colour is visible in the rendered image although two other curves lie on it.
    fig.canvas.draw()
    rgb = np.asarray(fig.canvas.buffer_rgba())[..., :3].astype(int)
    red = np.all(np.abs(rgb - [0xd6, 0x27, 0x28]) < 30, axis=-1)
    assert red.sum() > 200

    # highlight= features another model; highlight=False none.
    fig = plot.accumulated_error(T, preds, REF, highlight="map")
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    assert lines["MapBaseline"].get_color() == plot.FEATURED_COLOR
    assert lines["MapBaseline"].get_zorder() > lines["CSympNet-ID"].get_zorder()
    assert legend_texts(fig) == ["MapBaseline", "pHNN2", "CSympNet-ID"]
    fig = plot.trajectory(T, preds, REF, highlight=False)
    assert all(ln.get_color() != plot.FEATURED_COLOR for ln in fig.axes[0].get_lines())
    with pytest.raises(ValueError, match="highlight: 'dhnn' is not one of the labels"):
        plot.trajectory(T, preds, REF, highlight="dhnn")


def test_bars_feature_csympnet_first():
    series = {"map": [[1.0, 2.0]], "csympnet": [[0.1, 0.2]], "ode": [[3.0, 4.0]]}
    fig = plot.bars(["g"], series, ylabel="err (a.u.)", log=True)
    ax = fig.axes[0]
    assert legend_texts(fig) == ["CSympNet-ID", "MapBaseline", "ODEBaseline"]
    bars = sorted(ax.patches, key=lambda p: p.get_x())
    first = bars[0]
    assert first.get_height() == pytest.approx(0.15)  # CSympNet-ID's median, leftmost
    assert first.get_zorder() > bars[1].get_zorder() and first.get_alpha() == 1.0
    assert ax.get_ylabel() == "err (a.u., log scale)"
    fig = plot.lambda_vs_noise([0], {"map": [[0.99]], "csympnet": [[0.99]]}, 0.99)
    assert legend_texts(fig) == ["$\\lambda^*$", "CSympNet-ID", "MapBaseline"]


def test_size_presets_fonts_and_wrapping():
    energies = {k: 0.5 * np.sum(v ** 2, axis=1) for k, v in PREDS.items()}
    page = plot.rollout_figure(T, PREDS, REF, energies=energies)  # size="page" by default
    column = plot.rollout_figure(T, PREDS, REF, energies=energies, size="column")
    assert page.get_size_inches()[0] == pytest.approx(7.2)
    assert column.get_size_inches()[0] == pytest.approx(3.5)
    # page: the four panels in one row; column: wrapped onto two rows of two.
    page_rows = {round(ax.get_position().y0, 3) for ax in panels(page)}
    column_rows = {round(ax.get_position().y0, 3) for ax in panels(column)}
    assert len(panels(page)) == len(panels(column)) == 4
    assert len(page_rows) == 1 and len(column_rows) == 2
    assert 3.0 < column.get_size_inches()[1] < 4.5 and page.get_size_inches()[1] < 3.0
    # Font sizes of the preset: 9/8 pt (page), 8/7 pt (column).
    ax = panels(page)[1]
    assert ax.xaxis.label.get_fontsize() == 9 and ax.get_xticklabels()[0].get_fontsize() == 8
    ax = panels(column)[1]
    assert ax.xaxis.label.get_fontsize() == 8 and ax.get_xticklabels()[0].get_fontsize() == 7
    # Single panels: column by default; page on request; an explicit (width, height).
    assert tuple(plot.trajectory(T, PREDS, REF).get_size_inches())[0] == pytest.approx(3.5)
    assert plot.energy(T, energies, size="page").get_size_inches()[0] == pytest.approx(7.2)
    assert tuple(plot.trajectory(T, PREDS, REF, size=(3.0, 2.0)).get_size_inches()) == \
        pytest.approx((3.0, 2.0))
    for bad in ("poster", (3.0,), (0.0, 2.0)):
        with pytest.raises(ValueError, match="size:"):
            plot.phase_portrait(PREDS, REF, size=bad)


def test_axis_labels_carry_units_and_log_scale():
    fig = plot.trajectory(T, PREDS, REF)
    assert fig.axes[0].get_xlabel() == "time $t$ (a.u.)"
    assert fig.axes[0].get_ylabel() == "$q_{1}$ (a.u.)"
    units = {"t": "s", "q": "m", "p": "kg m/s", "H": "J", "E": "m s$^{1/2}$"}
    fig = plot.phase_portrait(PREDS, REF, units=units)
    assert (fig.axes[0].get_xlabel(), fig.axes[0].get_ylabel()) == ("$q_{1}$ (m)", "$p_{1}$ (kg m/s)")
    fig = plot.accumulated_error(T, PREDS, REF, units=units)
    assert fig.axes[0].get_xlabel() == "time $t$ (s)"
    assert fig.axes[0].get_ylabel() == "$L^2$ error $E(t)$\n(m s$^{1/2}$, log scale)"
    fig = plot.accumulated_error(T, PREDS, REF, log=False, units={"E": ""})
    assert fig.axes[0].get_ylabel() == "$L^2$ error $E(t)$"
    fig = plot.energy(T, {"csympnet": np.ones(51)}, units=units)
    assert fig.axes[0].get_ylabel() == "energy $H$ (J)"
    with pytest.raises(ValueError, match=r"units: unknown quantities \['x'\]"):
        plot.trajectory(T, PREDS, REF, units={"x": "m"})


def reproduction_dir(root):
    """A small directory in the layout `csympnet reproduce` writes: a table suite with one
    rollout per model and a noise grid."""
    runs = root / "runs"
    runs.mkdir(parents=True)
    energy = lambda z: (0.5 * np.sum(z ** 2, axis=1)).tolist()
    summary = {"suites": ["table2", "noise"],
               "table2": {"title": "Table 2: L2 rollout error", "kind": "table", "s1": {}},
               "noise": {"title": "noise", "kind": "grid", "vary": "sigma", "s1": {}}}
    for i, model in enumerate(["csympnet", "sympnet", "phnn2"]):
        z = REF + (0 if model == "phnn2" else 1e-3 * (i + 1)) * np.cos(T)[:, None]
        key = f"table2-s1-{model}"
        (runs / f"{key}.json").write_text(json.dumps({"key": key, "status": "ok", "trajectory": {
            "t": T.tolist(), "reference": REF.tolist(), "prediction": z.tolist(),
            "energy_ref": energy(REF), "energy_pred": energy(z)}}))
        summary["table2"]["s1"][model] = {"key": key, "status": "ok"}
        stat = lambda v: {"values": v}
        summary["noise"]["s1"][model] = [
            {"sigma": s, "lambda_star": 0.99, "l2_error": stat([0.1 * (i + 1) + s, 0.2]),
             "lambda_hat": stat([0.99, 0.9901]), "gamma_abs_err": stat([1e-4, 2e-4])}
            for s in (0.0, 0.01)]
    (root / "summary.json").write_text(json.dumps(summary))
    return root


@pytest.mark.parametrize("size, width", [("column", 3.5), ("page", 7.2), (None, None)])
def test_figures_script_sizes(tmp_path, size, width):
    out = reproduction_dir(tmp_path / "rep")
    args = [sys.executable, str(SOURCE_DIR / "experiments" / "figures.py"), str(out)]
    if size:
        args += ["--size", size]
    p = subprocess.run(args, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    names = sorted(os.listdir(out / "figures"))
    assert names == sorted(f"{n}.{e}" for n in ("table2-s1-rollout", "noise-s1-l2", "noise-s1-lambda",
                                                 "noise-s1-gamma") for e in ("png", "pdf"))
    for name in names:
        if name.endswith(".pdf"):
            assert "Type3" not in pdf_fonts(out / "figures" / name), name
    # The PNG width in pixels is the preset's width at 300 dpi ("auto": rollouts page wide,
    # bar charts column wide).
    def png_width(name):
        return int.from_bytes((out / "figures" / name).read_bytes()[16:20], "big") / 300
    rollout = width or 7.2
    bars = width or 3.5
    assert png_width("table2-s1-rollout.png") == pytest.approx(rollout, abs=0.01)
    assert png_width("noise-s1-l2.png") == pytest.approx(bars, abs=0.01)
    bad = subprocess.run(args[:3] + ["--size", "poster"], capture_output=True, text=True)
    assert bad.returncode != 0 and "--size" in bad.stderr


def test_each_model_type_keeps_its_colour_across_figures():
    colours = lambda fig: {ln.get_label(): ln.get_color() for ln in fig.axes[0].get_lines()}
    a = colours(plot.trajectory(T, {"csympnet": REF, "dhnn2": REF, "phnn2": REF}, REF))
    b = colours(plot.trajectory(T, {"map": REF, "ode": REF, "dhnn2": REF, "phnn2": REF}, REF))
    assert a["DHNN2"] == b["DHNN2"] == plot.MODEL_COLORS["dhnn2"]
    assert a["pHNN2"] == b["pHNN2"] and a["CSympNet-ID"] == plot.FEATURED_COLOR
    # Labels that are not model types get distinct colours, none of them the featured one.
    c = colours(plot.trajectory(T, {f"run {i}": REF for i in range(20)}, None))
    assert len(set(list(c.values())[:12])) == 12 and plot.FEATURED_COLOR not in c.values()


def test_error_unit_follows_the_units_passed():
    fig = plot.accumulated_error(T, PREDS, REF, log=False, units={"t": "s", "q": "m", "p": "m"})
    assert fig.axes[0].get_ylabel() == "$L^2$ error $E(t)$\n(m s$^{1/2}$)"
    fig = plot.accumulated_error(T, PREDS, REF, log=True,
                                 units={"t": "s", "q": "deg", "p": "deg/s"})
    assert fig.axes[0].get_ylabel() == "$L^2$ error $E(t)$\n((deg, deg/s) s$^{1/2}$,\nlog scale)"
    fig = plot.rollout_figure(T, PREDS, REF, units={"t": "s", "q": "deg", "p": "deg/s"})
    assert "a.u." not in fig.axes[2].get_ylabel()


def test_curves_lying_on_one_another_stay_distinguishable():
    # On S1 the four Hamiltonian baselines' rollouts coincide: each needs its own dashes and
    # markers, the markers at different points of the curve.
    same = damped(T, gamma=0.02)
    preds = {"csympnet": REF, "dhnn": same, "dhnn2": same, "phnn": same, "phnn2": same}
    fig = plot.trajectory(T, preds, REF)
    lines = {ln.get_label(): ln for ln in fig.axes[0].get_lines()}
    four = [lines[k] for k in ("DHNN", "DHNN2", "pHNN", "pHNN2")]
    assert len({ln.get_marker() for ln in four}) == 4
    assert len({str(ln._unscaled_dash_pattern) for ln in four}) == 4
    assert len({ln.get_markevery()[0] for ln in four}) == 4


def test_a_caption_goes_below_the_panels(tmp_path):
    fig = plot.rollout_figure(T, PREDS, REF, caption="Table 2, preset s1: rollouts.",
                              path=tmp_path / "cap")
    assert fig._suptitle is None
    texts = [t for ax in fig.axes for t in ax.texts if t.get_text() == "Table 2, preset s1: rollouts."]
    assert len(texts) == 1
    fig.canvas.draw()
    cap = texts[0].get_window_extent()
    assert all(cap.y1 <= ax.get_window_extent().y0 + 1 for ax in fig.axes[:3])


def test_frequency_response_draws_magnitude_phase_modes_and_settled_amplitudes(tmp_path):
    # an oscillator's response in closed form, as Model.frequency_response returns it
    w = np.geomspace(0.2, 5.0, 120)
    g = (1.5 / (4.0 - w**2 + 0.1j * w)).reshape(-1, 1, 1)
    linear = {"omega": w, "response": g, "modes": [(2.0, 0.025)]}
    ws = np.array([0.5, 1.0, 2.0, 3.0])
    sim = {"omega": ws, "amplitude": 0.3, "input_index": 0,
           "response": (1.5 / (4.0 - ws**2 + 0.1j * ws)).reshape(-1, 1),
           "settled": np.array([True, True, False, True])}
    fig = plot.frequency_response(linear, [sim], units={"t": "s"}, path=tmp_path / "bode")
    assert (tmp_path / "bode.png").exists() and (tmp_path / "bode.pdf").exists()
    mag, phase = fig.axes[0], fig.axes[1]
    assert mag.get_xscale() == "log" and mag.get_yscale() == "log"
    assert phase.get_xscale() == "log"
    line = mag.get_lines()[0]
    assert np.allclose(line.get_ydata(), np.abs(g[:, 0, 0]))
    # the phase falls through -90 degrees at the mode
    ph = phase.get_lines()[0].get_ydata()
    assert ph[0] > -5 and ph[-1] < -170
    # the mode is marked on both panels; the point that did not settle is left out
    assert any(len(ln.get_xdata()) == 2 and np.allclose(ln.get_xdata(), [2.0, 2.0])
               for ln in mag.get_lines())
    points = [ln for ln in mag.get_lines() if ln.get_marker() == "o"][0]
    assert np.allclose(points.get_xdata(), [0.5, 1.0, 3.0])
    with pytest.raises(ValueError, match="output, input"):
        plot.frequency_response(linear, output=1)
