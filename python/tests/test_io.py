"""Model files: Python ↔ Python and CLI ↔ Python, with bit-identical predictions."""

import io
import json

import numpy as np
import pytest

import csympnet

Z0 = np.array([0.5, -0.2])


def rollout_csv(run_cli, model_path, z0, h, steps):
    out = run_cli("rollout", "--model", model_path, "--z0", ",".join(repr(float(x)) for x in z0),
                  "--h", repr(h), "--steps", steps).stdout
    return np.loadtxt(io.StringIO(out), delimiter=",", skiprows=1, ndmin=2)


def test_save_load_round_trip(tmp_path, s1_model):
    path = tmp_path / "m.json"
    s1_model.meta["note"] = "kept"
    s1_model.save(path)
    back = csympnet.load(path)
    assert np.array_equal(back.params, s1_model.params)
    assert back.gamma == s1_model.gamma and back.hyperparams == s1_model.hyperparams
    assert back.meta["note"] == "kept" and back.training is None
    z = np.random.default_rng(0).uniform(-1, 1, (9, 2))
    assert np.array_equal(back.predict(z, 0.13), s1_model.predict(z, 0.13))
    doc = json.loads(path.read_text())
    assert doc["format"] == "csympnet-model" and doc["n_params"] == 115
    text = s1_model.to_json()
    assert np.array_equal(csympnet.from_json(text).params, s1_model.params)


def test_python_model_in_the_cli(tmp_path, run_cli, s1_model):
    path = tmp_path / "py.json"
    s1_model.save(path)
    # rollout: the CLI prints t, q, p with 17 significant digits → the same doubles.
    table = rollout_csv(run_cli, path, Z0, 0.2, 50)
    ours = s1_model.rollout(Z0, 0.2, steps=50)
    np.testing.assert_array_equal(table[:, 0], 0.2 * np.arange(51))
    assert np.array_equal(table[:, 1:], ours)
    # evaluate: every scalar equal.
    cli = json.loads(run_cli("evaluate", "--model", path, "--preset", "s1").stdout)
    py = s1_model.diagnostics(preset="s1", per_point=False)
    for key in ("l2_error", "residual_mean", "residual_max", "lambda_hat_mean",
                "lambda_abs_err_mean", "lambda_star", "structure_residual_mean",
                "structure_residual_max", "jacobian_points", "gamma_hat", "gamma_abs_err"):
        assert cli[key] == py[key], key
    # Without --preset the CLI takes the system recorded in meta.
    cli2 = json.loads(run_cli("evaluate", "--model", path, "--data", _tests_csv(tmp_path, py)).stdout)
    assert cli2["l2_error"] == py["l2_error"]


def _tests_csv(tmp_path, diagnostics):
    path = tmp_path / "tests.csv"
    csympnet.write_csv(path, diagnostics["tests"])
    return path


def test_cli_model_in_python(tmp_path, run_cli):
    out = tmp_path / "run"
    run_cli("run", "--preset", "s1", "--epochs", 200, "--out", out, "-q")
    model = csympnet.load(out / "model.json")
    report = json.loads((out / "report.json").read_text())
    assert model.gamma == report["gamma_hat"] and model.meta["preset"] == "s1"
    # The CLI's rollouts of the test set, reproduced to the bit.
    rollouts = csympnet.read_csv(out / "rollout.csv")
    reference = csympnet.read_csv(out / "reference.csv")
    for pred, ref in zip(rollouts, reference):
        assert np.array_equal(model.rollout(ref.z[0], np.diff(ref.t)), pred.z)
    dg = model.diagnostics(per_point=False)  # system from the file's meta
    assert dg["l2_error"] == report["l2_error"]
    assert dg["residual_mean"] == report["residual_mean"]
    # And the CLI's rollout command agrees with Python's.
    assert np.array_equal(rollout_csv(run_cli, out / "model.json", Z0, 0.1, 20)[:, 1:],
                          model.rollout(Z0, 0.1, steps=20))


def test_vector_field_model_round_trip(tmp_path, run_cli):
    out = tmp_path / "ode"
    run_cli("run", "--preset", "s1", "--model", "ode", "--epochs", 30, "--out", out, "-q")
    model = csympnet.load(out / "model.json")
    assert model.type == "ode" and model.gamma is None
    assert np.array_equal(rollout_csv(run_cli, out / "model.json", Z0, 0.2, 5)[:, 1:],
                          model.rollout(Z0, 0.2, steps=5))
    model.save(tmp_path / "again.json")
    assert np.array_equal(csympnet.load(tmp_path / "again.json").predict(Z0, 0.2),
                          model.predict(Z0, 0.2))


def test_bad_model_files(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(csympnet.Error, match="bad.json: not valid JSON"):
        csympnet.load(bad)
    bad.write_text(json.dumps({"format": "csympnet-model", "version": 2,
                               "model": {"type": "csympnet", "d": 1,
                                         "core": {"type": "la", "layers": 1, "sublayers": 1}},
                               "params": [0.0]}))
    with pytest.raises(csympnet.Error, match="architecture needs"):
        csympnet.load(bad)
    # A downgrade to version 1, which had no checksum, is refused: edited parameters could
    # otherwise pass as a genuine old file.
    doc = json.loads(bad.read_text())
    doc["version"] = 1
    bad.write_text(json.dumps(doc))
    with pytest.raises(csympnet.Error, match="version 1 .no checksum. is no longer read"):
        csympnet.load(bad)
    with pytest.raises(csympnet.Error, match="no such file"):
        csympnet.load(tmp_path / "missing.json")


def test_batch_predict_equals_cli_steps_for_d10(tmp_path, run_cli, s2_model):
    # d = 10: batched products round differently, so this checks predict() steps each state
    # exactly as the CLI does.
    path = tmp_path / "s2.json"
    s2_model.save(path)
    z = np.random.default_rng(5).uniform(-1, 1, (4, 20))
    batch = s2_model.predict(z, 0.1)
    for i in range(4):
        assert np.array_equal(rollout_csv(run_cli, path, z[i], 0.1, 1)[1, 1:], batch[i])
