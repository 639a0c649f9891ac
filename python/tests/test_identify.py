"""csympnet.identify: the same recipe and bits as `csympnet fit`, the verdict as a warning,
argument checks."""

import json
import subprocess
import warnings

import numpy as np
import pytest

import csympnet


def damped_oscillator(n=160, gamma=0.1, sigma=0.0, seed=0, scale=(1.0, 1.0)):
    """One trajectory of q'' + γ q' + q = 0 at irregular steps (exact flow)."""
    rng = np.random.default_rng(seed)
    w = np.sqrt(1.0 - gamma * gamma / 4.0)
    t = np.cumsum(np.r_[0.0, rng.uniform(0.06, 0.14, n - 1)])
    e = np.exp(-gamma * t / 2.0)
    q = e * np.cos(w * t)
    p = e * (-gamma / 2.0 * np.cos(w * t) - w * np.sin(w * t))
    z = np.stack([q, p], axis=1)
    z += sigma * z.std(axis=0) * rng.standard_normal(z.shape)
    return t, z * np.asarray(scale)


SMALL = dict(epochs=400, lm_iterations=20, core="la:3:6")


def test_identifies_gamma_with_an_interval():
    t, z = damped_oscillator(sigma=1e-3)
    r = csympnet.identify(z, t, **SMALL)
    assert r.identified, r.reasons
    low, high = r.interval
    assert low < r.gamma < high
    assert abs(r.gamma - 0.1) < 0.02
    assert r.report["choices"]["core"]["type"] == "la"
    assert "Identification(gamma=" in repr(r)
    # The model works in the data's units and is exactly conformally symplectic there.
    s = r.model.structure(z[3], 0.1)
    assert s["structure_residual"] < 1e-12
    # Its one mode: ω = 1 and ζ = γ̂ / 2, with intervals; the estimator says the same.
    (mode,) = r.modes
    assert abs(mode["angular_frequency"] - 1.0) < 0.01
    assert abs(r.damping_ratios[0] - r.gamma / (2.0 * r.frequencies[0])) < 1e-9
    low, high = mode["angular_frequency_interval"]
    assert low < mode["angular_frequency"] < high
    est = csympnet.CSympNetID(**SMALL).fit(z, t)
    assert np.array_equal(est.frequencies_, r.frequencies)
    assert np.array_equal(est.damping_ratio_, r.damping_ratios)


def test_units_do_not_change_the_answer():
    t, z = damped_oscillator(sigma=1e-3)
    ref = csympnet.identify(z, t, **SMALL)
    scaled = csympnet.identify(z * np.array([57.3, 1e3]) + np.array([30.0, 0.0]), t * 60.0, **SMALL)
    width = ref.interval[1] - ref.interval[0]
    assert abs(scaled.gamma * 60.0 - ref.gamma) < 1e-5 * width


def test_same_bits_as_the_cli(tmp_path, cli):
    t, z = damped_oscillator(sigma=1e-2, seed=3)
    path = tmp_path / "traj.csv"
    csympnet.write_csv(str(path), [csympnet.Trajectory(t, z)])
    out = tmp_path / "fit"
    code = subprocess.run([cli, "fit", str(path), "--out", str(out), "-q", "--epochs", "400",
                           "--lm-iterations", "20", "--core", "la:3:6"],
                          capture_output=True, text=True).returncode
    assert code in (0, 4)
    rep = json.loads((out / "report.json").read_text())
    r = csympnet.identify(z, t, **SMALL)
    assert r.gamma == rep["gamma_hat"]
    assert r.interval[0] == rep["gamma_ci_low"]


def test_not_identified_warns_and_says_why():
    rng = np.random.default_rng(1)
    z = rng.standard_normal((150, 2))
    t = np.arange(150) * 0.1
    with pytest.warns(csympnet.NotIdentifiedWarning, match="not identified"):
        r = csympnet.identify(z, t, **SMALL)
    assert not r.identified
    assert r.reasons
    assert "not identified" in repr(r)


def test_pairs_and_checks():
    t, z = damped_oscillator(n=120)
    pairs = (z[:-1], z[1:], np.diff(t))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", csympnet.NotIdentifiedWarning)
        r = csympnet.identify(pairs=pairs, **SMALL)
    assert r.report["data"]["pairs_file"] is True
    with pytest.raises(ValueError, match="t: the sample times"):
        csympnet.identify(z)
    with pytest.raises(ValueError, match="loss"):
        csympnet.identify(z, t, loss="l1")
    with pytest.raises(ValueError, match="not both"):
        csympnet.identify(z, t, pairs=pairs)
    with pytest.raises(ValueError):
        csympnet.identify(z, t, level=1.5)


def test_growing_motion_is_rejected_with_a_warning_and_its_rate():
    t, z = damped_oscillator(n=200, gamma=-0.1, sigma=1e-2, seed=5)
    with pytest.warns(csympnet.ModelRejectedWarning, match="the motion grows"):
        r = csympnet.identify(z, t, **SMALL)
    assert not r.identified and r.verdict == "model rejected"
    assert r.gamma is None and r.interval is None and r.estimate is not None
    names = [c["name"] for c in r.checks]
    assert names == ["measured_momenta", "dissipation", "linear_damping", "one_rate", "residuals"]
    assert r.checks[0]["passed"] is True  # the momenta are measured (their own noise)
    growth = r.checks[1]
    assert growth["passed"] is False
    low, high = growth["details"]["reversed_time_fit"]["interval"]
    assert low < 0.1 < high
    # The estimator says the same (one pipeline).
    with pytest.warns(csympnet.NotIdentifiedWarning):
        est = csympnet.CSympNetID(**SMALL).fit(z, t)
    assert est.verdict_ == "model rejected" and est.gamma_ is None
    assert est.frequencies_ is None and est.damping_ratio_ is None
    assert est.checks_ == r.checks


def test_positions_alone_one_answer_in_python_the_estimator_and_the_cli(tmp_path, cli):
    """Positions alone: the momenta are hidden states; identify, CSympNetID and `csympnet fit`
    on a positions file give the same γ̂ and interval, and momenta from numpy.gradient of the
    same noisy positions are set aside for the same answer."""
    t, z = damped_oscillator(n=300, sigma=1e-2, seed=7)
    q = z[:, 0]
    r = csympnet.identify(q, t, observed="positions", **SMALL)
    assert r.report["observed"] == "positions"
    assert r.identified, r.reasons
    low, high = r.interval
    assert low < 0.1 < high
    est = csympnet.CSympNetID(observed="positions", **SMALL).fit(q[:, None], t)
    assert est.gamma_ == r.gamma and est.gamma_interval_ == r.interval
    with pytest.raises(ValueError, match="state_from_positions"):
        est.score(q[:, None], t)
    path = tmp_path / "positions.csv"
    path.write_text("t,q1\n" + "".join(f"{a!r},{b!r}\n" for a, b in zip(t, q)))
    out = tmp_path / "fit"
    subprocess.run([cli, "fit", str(path), "--out", str(out), "-q", "--epochs", "400",
                    "--lm-iterations", "20", "--core", "la:3:6"], capture_output=True, text=True)
    rep = json.loads((out / "report.json").read_text())
    assert rep["gamma_hat"] == r.gamma and rep["gamma_ci_low"] == r.interval[0]
    differenced = np.stack([q, np.gradient(q, t)], axis=1)
    d = csympnet.identify(differenced, t, **SMALL)
    assert d.report["observed"] == "positions"
    assert "momenta_set_aside" in d.report["choices"]
    assert d.gamma == r.gamma
    with pytest.raises(ValueError, match="needs trajectories"):
        csympnet.identify(pairs=(z[:-1], z[1:], np.diff(t)), observed="positions")
    with pytest.raises(ValueError, match="observed"):
        csympnet.identify(q, t, observed="velocities")


def test_a_forecast_from_positions_alone():
    """Model.state_from_positions: the momenta of a recent window fitted with the model, then a
    rollout forecasts the positions that follow."""
    t, z = damped_oscillator(n=300, sigma=1e-3, seed=8)
    q = z[:, 0]
    r = csympnet.identify(q, t, observed="positions", **SMALL)
    state, rms = r.model.state_from_positions(q[200:230], t[200:230])
    assert state.shape == (2,)
    assert rms < 5e-3
    steps = np.diff(t[229:260])
    forecast = r.model.rollout(state, steps)[:, 0]
    assert np.max(np.abs(forecast - q[229:260])) < 0.02
    with pytest.raises(ValueError, match="positions"):
        r.model.state_from_positions(np.zeros((5, 2)), np.arange(5.0))
    with pytest.raises(ValueError, match="increasing"):
        r.model.state_from_positions(q[:5], t[:5][::-1])


def test_the_library_core_reports_its_hamiltonian_the_same_everywhere(tmp_path, cli):
    """One answer about H: identify, the estimator and `csympnet fit` give the same terms,
    coefficients and intervals; in the data's units (q scaled by 3, time by 10)."""
    t, z = damped_oscillator(sigma=1e-3)
    t, z = 10.0 * t, z * np.array([3.0, 0.3])
    r = csympnet.identify(z, t, core="library")
    assert r.report["choices"]["core"]["type"] == "library"
    h = r.hamiltonian
    terms = {x["term"]: x for x in h["terms"]}
    # q'' + q = 0 with q_file = 3q, p_file = 0.3p, t_file = 10t: H_file = (3 * 0.3 / 10) H,
    # V = 0.09 * (q_file / 3)^2 / 2 = 0.005 q_file^2; inverse mass 0.09 / 0.3^2 = 1.
    c = terms["q1^2"]
    assert c["interval"][0] <= 0.005 <= c["interval"][1], c
    assert abs(h["inverse_mass"][0][0] - 1.0) < 0.01
    est = csympnet.CSympNetID(core="library").fit(z, t)
    assert est.hamiltonian_ == h
    data = tmp_path / "d.csv"
    np.savetxt(data, np.c_[t, z], delimiter=",", header="t,q1,p1", comments="")
    out = tmp_path / "fit"
    subprocess.run([cli, "fit", str(data), "--out", str(out), "--core", "library", "-q"],
                   check=True, capture_output=True)
    assert json.loads((out / "report.json").read_text())["hamiltonian"] == h


def test_given_library_terms_are_fitted_as_given():
    t, z = damped_oscillator()
    r = csympnet.identify(z, t, core={"type": "library", "terms": ["q1", "q1^2"]})
    assert r.report["choices"]["core"]["terms"] == ["q1", "q1^2"]
    assert abs(r.gamma - 0.1) < 1e-6
    with pytest.raises(Exception, match="q1\\^9"):
        csympnet.identify(z, t, core={"type": "library", "terms": ["q1^9"]})


def test_lists_of_trajectories_of_different_d_are_refused_naming_the_entry():
    """A list of position (or state) arrays whose d differ: the entry and both dimensions are
    named (the library once said "expected 1 position rows", or that trajectories differ)."""
    t = np.arange(100) * 0.1
    one = np.cos(t)[:, None]
    two = np.stack([np.cos(t), np.sin(t)], axis=1)
    with pytest.raises(ValueError, match=r"z\[1\]: 2 position columns \(d = 2\), but z\[0\] has "
                                         r"1 \(d = 1\); expected every trajectory"):
        csympnet.identify([one, two], [t, t], observed="positions")
    with pytest.raises(ValueError, match=r"z\[1\]: 1 position columns \(d = 1\), but z\[0\] has "
                                         r"2 \(d = 2\)"):
        csympnet.identify([two, np.cos(t)], [t, t], observed="positions")
    with pytest.raises(ValueError, match=r"z\[1\]: 4 state columns \(d = 2\), but z\[0\] has 2 "
                                         r"\(d = 1\)"):
        csympnet.identify([np.hstack([one, one]), np.hstack([two, two])], [t, t],
                          observed="states")


def test_record_fit_one_answer_in_python_the_estimator_and_the_cli(tmp_path, cli):
    """A record with momenta and the library core: the whole record is fitted (q and p
    observed) unless record_fit="windows"; the estimator and `csympnet fit --record-fit` give
    the same bits; a misspelt value is refused by name."""
    t, z = damped_oscillator(n=400, sigma=1e-2, seed=3)
    core = {"type": "library", "terms": ["q1^2"]}
    states = dict(core=core, observed="states")
    whole = csympnet.identify(z, t, **states)
    windows = csympnet.identify(z, t, **states, record_fit="windows")
    assert "whole_record" in whole.report["choices"]
    assert "whole_record" not in windows.report["choices"]
    assert whole.report["config"]["record_fit"] == "auto"
    assert whole.interval[0] <= 0.1 <= whole.interval[1]
    assert whole.interval[1] - whole.interval[0] < windows.interval[1] - windows.interval[0]
    est = csympnet.CSympNetID(**states, record_fit="windows").fit(z, t)
    assert est.gamma_ == windows.gamma
    data = tmp_path / "rec.csv"
    np.savetxt(data, np.c_[t, z], delimiter=",", header="t,q1,p1", comments="")
    out = tmp_path / "fit"
    subprocess.run([cli, "fit", str(data), "--out", str(out), "--core", json.dumps(core),
                    "--record-fit", "windows", "-q"], check=True, capture_output=True)
    rep = json.loads((out / "report.json").read_text())
    assert rep["gamma_hat"] == windows.gamma
    with pytest.raises(ValueError, match="record_fit"):
        csympnet.identify(z, t, **states, record_fit="segments")
