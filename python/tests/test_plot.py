"""csympnet.plot: every figure type renders to PNG and PDF, from plain arrays."""

import numpy as np
import pytest

pytest.importorskip("matplotlib")
from csympnet import plot  # noqa: E402


def damped(t, gamma=0.1, scale=1.0):
    return scale * np.exp(-gamma * t / 2)[:, None] * np.c_[np.cos(t), -np.sin(t)]


T = np.linspace(0.0, 10.0, 51)
REF = damped(T)
PREDS = {"csympnet": REF + 1e-6 * np.sin(T)[:, None], "map": damped(T, gamma=0.02)}


def written(tmp_path, name):
    return [(tmp_path / f"{name}{ext}").stat().st_size > 1000 for ext in (".png", ".pdf")]


def test_each_rollout_panel(tmp_path):
    fig = plot.phase_portrait(PREDS, REF, path=tmp_path / "phase")
    assert written(tmp_path, "phase") == [True, True]
    ax = fig.axes[0]
    assert ax.get_xlabel() == "$q_{1}$" and ax.get_ylabel() == "$p_{1}$"
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["reference", "CSympNet-ID", "MapBaseline"]
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
    assert len(fig.axes) == 4 and written(tmp_path / "sub", "rollout") == [True, True]
    assert len(plot.rollout_figure(T, PREDS, REF).axes) == 3


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
