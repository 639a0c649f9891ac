"""The figure of a `csympnet fit` output directory (csympnet.fit_figure, plot.fit_figure) on a
record with momenta, on positions alone, on several trajectories of d = 4, and unidentified;
and rollout_figure with a reference of positions alone."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

pytest.importorskip("matplotlib")
from conftest import SOURCE_DIR  # noqa: E402
from csympnet import fit_figure, plot  # noqa: E402

RECORD = SOURCE_DIR / "examples" / "pendulum_record.csv"
COLUMNS = "t=time_s,q1=angle_deg,p1=angular_velocity_deg_s"


def fitted(run_cli, tmp_path, data, *args, code=0):
    out = tmp_path / "out"
    p = run_cli("fit", data, "--out", out, "-q", "--no-figures", *args, check=False)
    assert p.returncode == code, p.stderr
    assert not (out / "fit.png").exists()  # --no-figures
    return out


def drawn(base):
    sizes = [os.path.getsize(f"{base}{ext}") for ext in (".png", ".pdf")]
    assert all(s > 10_000 for s in sizes), sizes
    assert open(f"{base}.png", "rb").read(8) == b"\x89PNG\r\n\x1a\n"
    assert open(f"{base}.pdf", "rb").read(5) == b"%PDF-"


def texts(fig):
    return " ".join([fig._suptitle.get_text()] + [t.get_text() for ax in fig.axes
                                                   for t in ax.texts + [ax.title]])


def test_state_record_with_its_own_column_names(run_cli, tmp_path):
    out = fitted(run_cli, tmp_path, RECORD, "--columns", COLUMNS)
    fig = plot.fit_figure(out, path=out / "fit")
    drawn(out / "fit")
    text = texts(fig)
    assert "angle_deg" in text and "from the first state" not in text  # the legend says it
    assert "per s" in text and "[" in text  # γ̂ with its interval, in the record's unit
    assert "mode 1" not in text and "1: ω" in text and "damping ratio ζ" in text
    # The amplitude panel's fitted line is A0 exp(−γ̂ t/2), at the report's γ̂.
    g = json.loads((out / "report.json").read_text())["gamma_hat"]
    amp = [ax for ax in fig.axes if "amplitude" in ax.get_title()][0]
    line = [ln for ln in amp.get_lines() if ln.get_linestyle() == "--"][0]
    t, a = line.get_data()
    assert np.allclose(np.diff(np.log(a)) / np.diff(t), -g / 2)


def test_positions_only_record_starts_from_a_fitted_state(run_cli, tmp_path):
    a = np.loadtxt(RECORD, delimiter=",", skiprows=1)
    data = tmp_path / "positions.csv"
    np.savetxt(data, a[:400, :2], delimiter=",", header="t,q1", comments="", fmt="%.10g")
    out = fitted(run_cli, tmp_path, data)
    fig = plot.fit_figure(out, path=out / "fit")
    drawn(out / "fit")
    q_ax = fig.axes[0]
    labels = [ln.get_label() for ln in q_ax.get_lines()]
    assert any("first 20 positions" in s for s in labels), labels
    # The free run starts at the window's last sample, not at the record's first.
    free = [ln for ln in q_ax.get_lines() if ln.get_label().startswith("free run")][0]
    assert free.get_xdata()[0] == pytest.approx(a[19, 0])


def test_many_dofs_and_trajectories_draw_the_longest(run_cli, tmp_path):
    d, rows, rng = 4, [], np.random.default_rng(3)
    k = 2 * np.eye(d) - np.eye(d, k=1) - np.eye(d, k=-1)
    for traj, n in ((0, 60), (1, 120)):
        z = rng.standard_normal(2 * d)
        for i in range(n):  # symplectic Euler with damping: a damped chain, h = 0.1
            rows.append([traj, 0.1 * i, *z])
            p = (z[d:] - 0.1 * k @ z[:d]) * np.exp(-0.1 * 0.1)
            z = np.r_[z[:d] + 0.1 * p, p]
    header = "traj,t," + ",".join([f"q{i}" for i in range(1, d + 1)] +
                                   [f"p{i}" for i in range(1, d + 1)])
    data = tmp_path / "chain.csv"
    np.savetxt(data, np.array(rows), delimiter=",", header=header, comments="", fmt="%.12g")
    out = tmp_path / "out"
    p = run_cli("fit", data, "--out", out, "-q", "--no-figures", "--epochs", "30",
                "--lm-iterations", "5", check=False)
    assert p.returncode in (0, 4, 5), p.stderr
    fig = fit_figure.draw(out, path=out / "fit")
    drawn(out / "fit")
    assert "trajectory 2 of 2 (the longest)" in fig._suptitle.get_text()
    assert any("every dof" in ax.get_title() for ax in fig.axes)  # the summary beyond q3
    assert sum("record and the model's free run" in ax.get_title() for ax in fig.axes) == 3


def test_unidentified_fit_says_so(run_cli, tmp_path):
    rng = np.random.default_rng(0)
    t = np.arange(0, 3, 0.1)
    data = tmp_path / "short.csv"
    np.savetxt(data, np.c_[t, np.cos(t) + 0.3 * rng.standard_normal(t.size),
                           -np.sin(t) + 0.3 * rng.standard_normal(t.size)],
               delimiter=",", header="t,q1,p1", comments="", fmt="%.10g")
    out = fitted(run_cli, tmp_path, data, code=4)
    fig = plot.fit_figure(out, path=out / "fit")
    drawn(out / "fit")
    assert "not identified" in fig._suptitle.get_text()
    assert "[" not in fig._suptitle.get_text()  # no interval


def test_driven_record_is_fed_its_inputs_and_shows_its_frequency_response(run_cli, tmp_path):
    from test_identify_inputs import GAMMA, OMEGA, driven_record  # the driven test oscillator
    q, t, u = driven_record(n=600)
    data = tmp_path / "driven.csv"
    np.savetxt(data, np.c_[t, q, u], delimiter=",", header="t,q1,u1", comments="", fmt="%.17g")
    out = fitted(run_cli, tmp_path, data)
    fig = plot.fit_figure(out, path=out / "fit")
    drawn(out / "fit")
    titles = [ax.get_title() for ax in fig.axes]
    assert any("frequency response" in t for t in titles)
    assert not any("amplitude" in t for t in titles)  # no free decay's envelope
    legend = " ".join(t.get_text() for ax in fig.axes if ax.get_legend()
                      for t in ax.get_legend().get_texts())
    assert "fed the inputs" in legend
    resp = [ax for ax in fig.axes if "frequency response" in ax.get_title()][0]
    mode = [ln for ln in resp.get_lines() if len(ln.get_xdata()) == 2][0].get_xdata()[0]
    assert abs(mode - OMEGA) < 0.01 * OMEGA  # the linearised mode, near the oscillator's
    curve = resp.get_lines()[0]
    w, mag = curve.get_data()
    assert abs(w[np.argmax(mag)] - np.sqrt(OMEGA**2 - GAMMA**2 / 2)) < 0.05  # the resonance
    # the free run follows the record: the residual panel's rms is near the noise
    res = [ax for ax in fig.axes if "residual" in ax.get_title()][0]
    r = res.get_lines()[0].get_ydata()
    assert np.sqrt(np.nanmean(r**2)) < 0.03 * q.std()


def test_module_command_fails_in_one_line(tmp_path, run_cli):
    out = fitted(run_cli, tmp_path, RECORD, "--columns", COLUMNS)
    p = subprocess.run([sys.executable, "-m", "csympnet.fit_figure", str(out), "--data",
                        str(tmp_path / "missing.csv")], capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 1
    assert p.stderr.count("\n") == 1 and p.stderr.startswith("fit_figure: "), p.stderr
    assert "missing.csv: not found" in p.stderr
    assert not (out / "fit.png").exists()


@pytest.mark.parametrize("layout", ["q columns", "NaN momenta"])
def test_rollout_figure_with_positions_alone(tmp_path, layout):
    t = np.linspace(0.0, 10.0, 51)
    ref = np.exp(-0.05 * t)[:, None] * np.c_[np.cos(t), -np.sin(t)]
    pred = ref + 1e-3
    reference = ref[:, :1] if layout == "q columns" else np.c_[ref[:, :1], np.full(51, np.nan)]
    fig = plot.rollout_figure(t, {"csympnet": pred}, reference, path=tmp_path / "r")
    drawn(tmp_path / "r")
    titles = [ax.get_title() for ax in fig.axes if ax.axison]
    assert titles == ["$q_{1}(t)$", "Accumulated error (positions)"], titles
    err = [ax for ax in fig.axes if ax.get_title().startswith("Accumulated")][0]
    y = err.get_lines()[0].get_ydata()
    assert np.all(np.isfinite(y)) and y[-1] > 0  # positions compared, not NaN
