"""Model: predict, rollout, jacobian, structure and diagnostics."""

import numpy as np
import pytest

import csympnet

J2 = np.array([[0.0, 1.0], [-1.0, 0.0]])


def canonical_j(d):
    return np.kron(J2, np.eye(d))


def test_predict_shapes_and_step_arrays(s1_model):
    z = np.random.default_rng(0).uniform(-1, 1, (7, 2))
    out = s1_model.predict(z, 0.1)
    assert out.shape == (7, 2) and out.dtype == np.float64
    assert s1_model.predict(z[3], 0.1).shape == (2,)
    assert np.array_equal(s1_model.predict(z[3], 0.1), out[3])
    hs = np.linspace(0.05, 0.15, 7)
    per_h = s1_model.predict(z, hs)
    assert all(np.array_equal(per_h[i], s1_model.predict(z[i], hs[i])) for i in range(7))
    assert not np.array_equal(per_h, out)
    # Integer input is read as float.
    assert np.array_equal(s1_model.predict([1, 0], 0.1), s1_model.predict([1.0, 0.0], 0.1))


def test_batched_predict_agrees_to_rounding(s2_model):
    z = np.random.default_rng(1).uniform(-1, 1, (30, 20))
    exact = s2_model.predict(z, 0.1)
    fast = s2_model.predict(z, 0.1, batched=True)
    assert all(np.array_equal(exact[i], s2_model.predict(z[i], 0.1)) for i in range(30))
    np.testing.assert_allclose(fast, exact, rtol=0, atol=1e-13)


def test_rollout_is_iterated_predict(s1_model):
    z0 = np.array([0.5, -0.2])
    hs = np.array([0.1, 0.2, 0.05, 0.2])
    out = s1_model.rollout(z0, hs)
    assert out.shape == (5, 2) and np.array_equal(out[0], z0)
    z = z0
    for n, h in enumerate(hs):
        z = s1_model.predict(z, h)
        assert np.array_equal(out[n + 1], z)
    same = s1_model.rollout(z0, 0.2, steps=3)
    assert np.array_equal(same, s1_model.rollout(z0, [0.2, 0.2, 0.2]))
    batch = s1_model.rollout(np.stack([z0, -z0]), hs)
    assert batch.shape == (2, 5, 2) and np.array_equal(batch[0], out)


def test_jacobian_matches_finite_differences(s1_model, s2_model):
    for model in (s1_model, s2_model):
        rng = np.random.default_rng(2)
        z = rng.uniform(-1, 1, 2 * model.d)
        jac = model.jacobian(z, 0.1)
        assert jac.shape == (2 * model.d, 2 * model.d)
        eps = 1e-6
        fd = np.empty_like(jac)
        for c in range(2 * model.d):
            e = np.zeros_like(z)
            e[c] = eps
            fd[:, c] = (model.predict(z + e, 0.1) - model.predict(z - e, 0.1)) / (2 * eps)
        np.testing.assert_allclose(jac, fd, atol=1e-8)
        batch = model.jacobian(np.stack([z, z]), [0.1, 0.2])
        assert batch.shape == (2, 2 * model.d, 2 * model.d) and np.array_equal(batch[0], jac)


def test_jacobian_is_conformally_symplectic(s1_model, s2_model):
    for model in (s1_model, s2_model):
        z = np.random.default_rng(3).uniform(-1, 1, (5, 2 * model.d))
        j = canonical_j(model.d)
        for m, h in zip(model.jacobian(z, 0.2), [0.2] * 5):
            np.testing.assert_allclose(m.T @ j @ m, np.exp(-model.gamma * h) * j, atol=1e-13)


def test_structure_per_state(s1_model):
    z = np.random.default_rng(4).uniform(-1, 1, (6, 2))
    s = s1_model.structure(z, 0.2, gamma_true=0.05)
    assert set(s) == {"R", "lambda_hat", "structure_residual"}
    np.testing.assert_allclose(s["lambda_hat"], np.exp(-0.2 * s1_model.gamma), rtol=1e-13)
    assert np.all(s["structure_residual"] < 1e-13)
    # d = 1: R = ‖(λ̂ − λ*) J‖_F = √2 |e^{−γ̂h} − e^{−γh}|. R is a difference of O(1) Jacobian
    # products, so its rounding error is absolute (a few ε), whatever R is: with γ̂ within 1e-7
    # of γ a relative tolerance would test the cancellation, not the formula.
    np.testing.assert_allclose(
        s["R"], np.sqrt(2) * abs(np.exp(-0.2 * s1_model.gamma) - np.exp(-0.2 * 0.05)), rtol=0,
        atol=1e-14)
    assert np.all(s["R"] > 1e-12)  # not vacuous: R is far above that rounding
    assert np.all(np.isnan(s1_model.structure(z, 0.2)["R"]))
    one = s1_model.structure(z[0], 0.2)
    assert np.isscalar(one["lambda_hat"]) or one["lambda_hat"].shape == ()


def test_sympnet_structure_is_area_preserving(s1_pairs):
    model = csympnet.fit(*s1_pairs, model="sympnet", epochs=30)
    s = model.structure(np.array([[0.3, 0.1], [-0.5, 0.2]]), 0.2)
    np.testing.assert_allclose(s["lambda_hat"], 1.0, rtol=1e-13)


def test_diagnostics_from_preset(s1_model):
    dg = s1_model.diagnostics(preset="s1")
    for key in ("l2_error", "residual_mean", "residual_max", "lambda_hat_mean",
                "lambda_abs_err_mean", "lambda_star", "structure_residual_mean",
                "structure_residual_max", "jacobian_points", "rollout_finite", "gamma_hat",
                "gamma_abs_err", "gamma_true", "h_test"):
        assert key in dg, key
    assert dg["gamma_hat"] == s1_model.gamma and dg["gamma_true"] == 0.05
    assert dg["jacobian_points"] == 10 * 51 and len(dg["rollouts"]) == 10
    assert dg["lambda_star"] == pytest.approx(np.exp(-0.05 * 0.2), rel=1e-15)
    pp = dg["per_point"]
    assert pp["R"].shape == (510,)
    assert np.mean(pp["R"]) == pytest.approx(dg["residual_mean"], rel=1e-12)
    assert np.max(pp["structure_residual"]) == pytest.approx(dg["structure_residual_max"], rel=1e-12)
    # The L2 error is the rollouts' quadrature error against the tests.
    sq = sum(np.sum((tr.z[1:] - r[1:]) ** 2 * np.diff(tr.t)[:, None])
             for tr, r in zip(dg["tests"], dg["rollouts"]))
    assert dg["l2_error"] == pytest.approx(np.sqrt(sq), rel=1e-12)
    # Energies: H = (q² + p²)/2 for s1.
    r = dg["rollouts"][0]
    np.testing.assert_allclose(dg["energy_pred"][0], 0.5 * np.sum(r ** 2, axis=1), rtol=1e-14)


def test_diagnostics_system_sources(s1_model):
    # meta["system"] (set by the fixture), an explicit dict, or a System give the same numbers.
    a = s1_model.diagnostics(per_point=False)
    b = s1_model.diagnostics(csympnet.systems["s1"]["system"], per_point=False)
    c = s1_model.diagnostics(csympnet.System.preset("s1"), per_point=False)
    assert a["l2_error"] == b["l2_error"] == c["l2_error"]
    other = s1_model.diagnostics(preset="s1", system={"gamma": 0.1}, per_point=False)
    assert other["gamma_true"] == 0.1 and other["l2_error"] != a["l2_error"]
    tests = a["tests"][:2]
    two = s1_model.diagnostics(tests=tests, h_test=0.1, per_point=False)
    assert two["jacobian_points"] == 2 * 51 and two["h_test"] == 0.1
    bare = csympnet.fit(*csympnet.generate("s1", "train", n=10), epochs=5)
    with pytest.raises(ValueError, match="does not record its system"):
        bare.diagnostics()
