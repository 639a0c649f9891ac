"""csympnet.CSympNetID: the estimator protocol scikit-learn relies on (clone, get/set_params,
pickle, cross_val_score), PySINDy's fit(x, t) forms, and what it reports on data in physical
units."""

import io
import pickle
import warnings

import numpy as np
import pytest

import csympnet

GAMMA = 0.05
STEP = 0.05
# Small budgets: these tests check the protocol, not the accuracy (tests/test_identify.py and
# bench/ measure that).
FAST = dict(epochs=150, lm_iterations=30)


def trajectory(z0, n, omega=2.0, scale=(180 / np.pi, 1000.0), noise=1e-3, seed=0):
    """A damped oscillator sampled every STEP, in degrees and milli-units, with noise."""
    sys_ = csympnet.System("oscillator", d=1, gamma=GAMMA, omega=omega)
    zs = [np.asarray(z0, dtype=float)]
    for _ in range(n - 1):
        zs.append(sys_.flow(zs[-1], STEP))
    z = np.array(zs) * np.asarray(scale)
    rng = np.random.default_rng(seed)
    return STEP * np.arange(n), z + rng.normal(0.0, noise * z.std(axis=0), z.shape)


@pytest.fixture(scope="module")
def long_run():
    return trajectory([0.6, 0.0], 800)


@pytest.fixture(scope="module")
def fitted(long_run):
    t, z = long_run
    return csympnet.CSympNetID(**FAST).fit(z, t)


def test_fit_reports_gamma_in_the_data_units_with_an_interval(fitted):
    assert fitted.identified_ and fitted.reasons_ == []
    low, high = fitted.gamma_interval_
    assert low < fitted.gamma_ < high
    assert abs(fitted.gamma_ - GAMMA) < 0.1 * GAMMA
    assert fitted.n_features_in_ == 2 and fitted.dt_ == pytest.approx(STEP)
    assert fitted.report_["identified"] is True


def test_score_predict_and_simulate(fitted, long_run):
    t, z = long_run
    held_t, held_z = trajectory([-0.4, 0.3], 200, seed=1)
    assert fitted.score(held_z, held_t) > 0.99
    # Predicting no change scores about 0; the score is R² over the increments.
    assert fitted.predict(z[:3]).shape == (3, 2)
    assert np.array_equal(fitted.predict(z[:3]), fitted.model_.predict(z[:3], fitted.dt_))
    sim = fitted.simulate(held_z[0], held_t[:50])
    assert sim.shape == (50, 2) and np.array_equal(sim[0], held_z[0])
    assert np.max(np.abs(sim - held_z[:50])) < 0.05 * np.max(np.abs(held_z))


def test_get_params_follow_the_signature_and_set_params_refuses_unknown_names():
    est = csympnet.CSympNetID(seed=3)
    params = est.get_params()
    assert params["seed"] == 3 and params["level"] == 0.95 and "verbose" in params
    assert est.set_params(level=0.9) is est and est.level == 0.9
    with pytest.raises(ValueError, match="unknown hyperparameter 'epoch'"):
        est.set_params(epoch=3)


def test_hyperparameters_are_checked_by_fit_not_by_init(long_run):
    t, z = long_run
    est = csympnet.CSympNetID(level=2.0)  # scikit-learn's rule: __init__ stores, fit checks
    with pytest.raises(ValueError, match="level"):
        est.fit(z, t)


def test_sklearn_clone_pickle_and_cross_val_score(fitted, long_run):
    base = pytest.importorskip("sklearn.base")
    model_selection = pytest.importorskip("sklearn.model_selection")
    twin = base.clone(fitted)
    assert twin.get_params() == fitted.get_params() and not hasattr(twin, "model_")

    copy = pickle.loads(pickle.dumps(fitted))
    t, z = long_run
    assert copy.gamma_ == fitted.gamma_ and copy.gamma_interval_ == fitted.gamma_interval_
    assert np.array_equal(copy.model_.params, fitted.model_.params)
    assert np.array_equal(copy.predict(z[:10]), fitted.predict(z[:10]))
    assert copy.model_.training == fitted.model_.training

    # Four trajectories as (K, M, 2d); KFold splits them whole.
    starts = [[0.6, 0.0], [-0.5, 0.2], [0.3, -0.4], [0.1, 0.5]]
    x = np.stack([trajectory(s, 300, seed=k)[1] for k, s in enumerate(starts)])
    est = csympnet.CSympNetID(t_default=STEP, **FAST)
    scores = model_selection.cross_val_score(est, x, cv=2)
    assert scores.shape == (2,) and np.all(scores > 0.99)


def test_the_accepted_data_forms_agree(long_run):
    t, z = long_run
    one = csympnet.CSympNetID(**FAST).fit(z, t)
    step = csympnet.CSympNetID(**FAST).fit(z, STEP)  # a step instead of the times
    listed = csympnet.CSympNetID(**FAST).fit([z], [t])
    stacked = csympnet.CSympNetID(**FAST).fit(z[None], t)
    for other in (step, listed, stacked):
        assert np.array_equal(other.model_.params, one.model_.params)
    pairs = csympnet.CSympNetID(**FAST).fit(z[:-1], STEP, x_next=z[1:])
    assert pairs.report_["data"]["pairs_file"] is True
    assert abs(pairs.gamma_ - GAMMA) < 0.2 * GAMMA


def test_data_that_do_not_identify_gamma_give_none_and_a_warning():
    rng = np.random.default_rng(4)
    z = rng.normal(size=(400, 2))  # noise: no dynamics to identify
    with pytest.warns(csympnet.NotIdentifiedWarning):
        est = csympnet.CSympNetID(**FAST).fit(z, STEP)
    assert est.identified_ is False and est.gamma_ is None and est.gamma_interval_ is None
    assert est.reasons_


def test_verbose_draws_a_progress_bar_per_stage(long_run, capsys):
    t, z = long_run
    csympnet.CSympNetID(verbose=True, **FAST).fit(z[:300], t[:300])
    assert "LM" in capsys.readouterr().err
    csympnet.CSympNetID(verbose=True, core="g:2:8", **FAST).fit(z[:300], t[:300])
    err = capsys.readouterr().err
    assert "AdamW" in err and "LM" in err
    with pytest.raises(TypeError, match="verbose"):
        csympnet.CSympNetID(verbose="yes", **FAST).fit(z[:300], t[:300])


def test_unfitted_estimator_says_so():
    with pytest.raises(RuntimeError, match="fit"):
        csympnet.CSympNetID().predict([0.0, 1.0])


def test_a_fit_model_pickles_with_its_training_summary():
    data = csympnet.generate("s1", "train")
    model = csympnet.fit(*data, epochs=50, bootstrap=0)
    copy = pickle.loads(pickle.dumps(model))
    assert np.array_equal(copy.params, model.params)
    assert copy.training == model.training and copy.meta == model.meta
    assert np.array_equal(copy.predict([0.5, -0.2], 0.1), model.predict([0.5, -0.2], 0.1))


def test_model_score_is_what_evaluate_data_reports(fitted, run_cli, tmp_path):
    """Model.score and `csympnet evaluate --model M --data traj.csv` are one computation."""
    held_t, held_z = trajectory([-0.4, 0.3], 120, seed=2)
    scores = fitted.model_.score(held_z, held_t)
    assert scores["pairs"] == 119 and len(scores["rollouts"]) == 1
    assert scores["rollouts"][0].shape == (120, 2)
    assert scores["one_step_r2"] == fitted.score(held_z, held_t)
    assert scores["gamma_hat"] == fitted.model_.gamma
    assert 0.0 < scores["valid_fraction_mean"] <= 1.0
    model_path, csv_path = tmp_path / "model.json", tmp_path / "held.csv"
    fitted.model_.save(model_path)
    csympnet.write_csv(csv_path, [csympnet.Trajectory(held_t, held_z)])
    import json
    report = json.loads(run_cli("evaluate", "--model", model_path, "--data", csv_path).stdout)
    observed = {k: v for k, v in scores.items() if k != "rollouts"}
    assert report["observed"] == observed
    assert report["gamma_true"] is None
    with pytest.raises(ValueError, match="states have 4 components, expected 2d = 2"):
        fitted.model_.score(np.zeros((5, 4)), np.arange(5.0))


def test_score_and_simulate_without_times_use_the_fitted_step(fitted, long_run):
    """After fit(z, t), score(z) and simulate(z0, steps=n) step by dt_, as predict does, not
    by t_default."""
    held_t, held_z = trajectory([-0.4, 0.3], 200, seed=1)
    assert fitted.t_default is None and fitted.dt_ == pytest.approx(STEP)
    assert fitted.score(held_z) == fitted.score(held_z, fitted.dt_)
    assert fitted.score(held_z) > 0.99
    assert fitted.score(held_z[:-1], x_next=held_z[1:]) == fitted.score(held_z)
    sim = fitted.simulate(held_z[0], steps=49)
    assert sim.shape == (50, 2)
    assert np.array_equal(sim, fitted.model_.rollout(held_z[0], fitted.dt_, steps=49))
    with pytest.raises(ValueError, match="steps"):
        fitted.simulate(held_z[0])
    with pytest.raises(ValueError, match="not both"):
        fitted.simulate(held_z[0], held_t[:5], steps=4)


def test_fit_without_times_warns_that_gamma_is_per_sample(long_run):
    t, z = long_run
    assert issubclass(csympnet.NoTimesWarning, UserWarning)
    with pytest.warns(csympnet.NoTimesWarning, match="per sample"):
        est = csympnet.CSympNetID(**FAST).fit(z[:300])
    assert est.dt_ == 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", csympnet.NoTimesWarning)
        csympnet.CSympNetID(t_default=STEP, **FAST).fit(z[:300])  # a step given: no warning
        csympnet.CSympNetID(**FAST).fit(z[:300], t[:300])
