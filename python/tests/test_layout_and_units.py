"""What a new user met: the layout of an array guessed silently, DataFrames, the clock's unit,
the interval lost in the model file, and a state fitted to a window it does not explain."""

import json
import warnings

import numpy as np
import pytest

import csympnet

SMALL = dict(epochs=400, lm_iterations=20, core="la:3:6")


def damped_oscillator(n=160, gamma=0.1, sigma=1e-3, seed=0):
    """One trajectory of q'' + γ q' + q = 0 at irregular steps (exact flow)."""
    rng = np.random.default_rng(seed)
    w = np.sqrt(1.0 - gamma * gamma / 4.0)
    t = np.cumsum(np.r_[0.0, rng.uniform(0.06, 0.14, n - 1)])
    e = np.exp(-gamma * t / 2.0)
    q = e * np.cos(w * t)
    p = e * (-gamma / 2.0 * np.cos(w * t) - w * np.sin(w * t))
    z = np.stack([q, p], axis=1)
    return t, z + sigma * rng.standard_normal(z.shape)


def test_an_array_read_as_states_without_observed_warns_naming_positions():
    t, z = damped_oscillator(n=40)
    assert issubclass(csympnet.LayoutWarning, UserWarning)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", csympnet.NotIdentifiedWarning)
        with pytest.warns(csympnet.LayoutWarning, match='observed="positions"'):
            csympnet.CSympNetID(epochs=20, lm_iterations=2, core="la:2:4").fit(z, t)
        with pytest.warns(csympnet.LayoutWarning, match=r"\(q1, p1\), d = 1"):
            csympnet.identify(z, t, epochs=20, lm_iterations=2, core="la:2:4")
        # Said once, or not at all when observed is given.
        with warnings.catch_warnings():
            warnings.simplefilter("error", csympnet.LayoutWarning)
            csympnet.identify(z, t, observed="states", epochs=20, lm_iterations=2,
                              core="la:2:4")
            csympnet.identify(pairs=(z[:-1], z[1:], np.diff(t)), epochs=20, lm_iterations=2,
                              core="la:2:4")
    # The default stays None, so clone and get_params see what was given.
    assert csympnet.CSympNetID().get_params()["observed"] is None


def test_the_time_unit_changes_the_report_not_the_fit():
    t, z = damped_oscillator()
    plain = csympnet.identify(z, t, observed="states", **SMALL)
    ms = csympnet.identify(z, t, observed="states", time_unit="ms", **SMALL)
    assert plain.identified, plain.reasons
    assert ms.gamma == plain.gamma and ms.interval == plain.interval
    assert plain.report["time_unit"] is None and plain.time_unit is None
    unit = ms.report["time_unit"]
    assert unit["unit"] == "ms" and unit["seconds_per_unit"] == 1e-3
    assert unit["gamma_per_s"] == pytest.approx(ms.gamma * 1e3, rel=1e-15)
    assert unit["gamma_ci_per_s"] == pytest.approx([x * 1e3 for x in ms.interval], rel=1e-15)
    assert unit["amplitude_decay_rate_per_s"] == pytest.approx(ms.gamma * 500.0, rel=1e-15)
    assert ms.gamma_per_s == unit["gamma_per_s"]
    assert ms.amplitude_decay_rate == ms.gamma / 2
    assert "per ms" in repr(ms)
    with pytest.raises(ValueError, match="time_unit"):
        csympnet.identify(z, t, observed="states", time_unit="fortnight", **SMALL)
    est = csympnet.CSympNetID(observed="states", time_unit="min", **SMALL).fit(z, t)
    assert est.gamma_ == plain.gamma
    assert est.time_unit_ == "min"
    assert est.gamma_per_s_ == pytest.approx(plain.gamma / 60.0, rel=1e-15)


def test_dataframes_are_read_by_column_name():
    pd = pytest.importorskip("pandas")
    t, z = damped_oscillator()
    ref = csympnet.identify(z, t, observed="states", **SMALL)
    states = pd.DataFrame({"p1": z[:, 1], "t": t, "q1": z[:, 0]})
    with warnings.catch_warnings():
        warnings.simplefilter("error", csympnet.LayoutWarning)
        r = csympnet.identify(states, **SMALL)
    assert r.gamma == ref.gamma and r.report["observed"] != "positions"
    # Positions under any names, times in ms named so: positions alone, the unit known.
    carts = pd.DataFrame({"timestamp_ms": t * 1e3, "left_cart_px": z[:, 0]})
    with warnings.catch_warnings():
        warnings.simplefilter("error", csympnet.LayoutWarning)
        # The frame's time column gives the times: no "per sample" warning.
        warnings.simplefilter("error", csympnet.NoTimesWarning)
        warnings.simplefilter("ignore", csympnet.NotIdentifiedWarning)
        est = csympnet.CSympNetID(**SMALL).fit(carts)
    assert est.report_["observed"] == "positions"
    assert est.time_unit_ == "ms"
    assert est.report_["time_unit"]["source"] == "column 'timestamp_ms'"
    with pytest.raises(ValueError, match="time column"):
        csympnet.identify(carts, t, **SMALL)


def test_a_fitted_interval_survives_the_model_file(tmp_path, run_cli):
    t, z = damped_oscillator()
    csv = tmp_path / "d.csv"
    csv.write_text("t_ms,x,v\n" + "".join(
        f"{a!r},{b!r},{c!r}\n" for a, b, c in zip(t, z[:, 0], z[:, 1])))
    out = run_cli("fit", csv, "--columns", "t=t_ms,q1=x,p1=v", "--core", "la:3:6",
                  "--epochs", "400", "--lm-iterations", "20", "--out", tmp_path / "fit").stdout
    report = json.loads((tmp_path / "fit" / "report.json").read_text())
    assert report["identified"], report["reasons"]
    assert report["time_unit"]["unit"] == "ms"
    assert "per ms" in out and "amplitude decay rate gamma/2" in out and "per s" in out
    model = csympnet.load(tmp_path / "fit" / "model.json")
    assert model.gamma_interval == (report["gamma_ci_low"], report["gamma_ci_high"])
    assert model.meta["gamma_interval_level"] == report["gamma_ci_level"]


def test_a_state_the_window_does_not_support_is_refused():
    t, z = damped_oscillator()
    q = z[:, :1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", csympnet.NotIdentifiedWarning)
        r = csympnet.identify(q, t, observed="positions", **SMALL)
    state, rms = r.model.state_from_positions(q[-30:], t[-30:])
    assert np.all(np.isfinite(state)) and rms < 0.1 * q[-30:].std()
    gap = np.r_[t[-30:-15], t[-15:] + 20.0]
    with pytest.raises(csympnet.Error, match="a gap"):
        r.model.state_from_positions(q[-30:], gap)
    with pytest.raises(csympnet.Error, match="does not explain"):
        r.model.state_from_positions(q[-30:] + 1e3 * np.linspace(0, 1, 30)[:, None] ** 3,
                                     t[-30:])


def test_rollout_from_positions_reads_own_columns_and_refuses_a_gap(tmp_path, run_cli):
    t, z = damped_oscillator(n=300, seed=8)
    q = z[:, 0]
    data = tmp_path / "positions.csv"
    data.write_text("t,q1\n" + "".join(f"{a!r},{b!r}\n" for a, b in zip(t, q)))
    run_cli("fit", data, "-q", "--epochs", "400", "--lm-iterations", "20", "--core", "la:3:6",
            "--out", tmp_path / "fit")
    model = tmp_path / "fit" / "model.json"

    def window(name, times):
        path = tmp_path / name
        path.write_text("time_s,x,temperature\n" + "".join(
            f"{a!r},{b!r},21\n" for a, b in zip(times, q[200:230])))
        return path

    args = ["rollout", "--model", model, "--h", "0.1", "--steps", "5", "--columns",
            "t=time_s,q1=x", "--from-positions"]
    out = run_cli(*args, window("w.csv", t[200:230])).stdout
    assert out.splitlines()[0] == "t,q1,p1" and len(out.splitlines()) == 7
    gap = np.r_[t[200:215], t[215:230] + 30.0]
    bad = run_cli(*args, window("gap.csv", gap), check=False)
    assert bad.returncode == 1, bad.stderr
    assert "a gap from t = " in bad.stderr and bad.stdout == ""
    # Without --columns the own header is refused, naming --columns.
    bad = run_cli(*args[:-3], "--from-positions", window("w2.csv", t[200:230]), check=False)
    assert bad.returncode == 1 and "--columns" in bad.stderr
