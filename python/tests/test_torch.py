"""csympnet.torch: the torch modules against the C++ models on the same model files, their exact
conformal symplecticity, and the files they write."""

import json

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import csympnet  # noqa: E402
import csympnet.torch as ct  # noqa: E402

# The architectures of every kind a module is built for, at sizes a test runs in milliseconds.
SPECS = {
    "csympnet-la-d1": {"type": "csympnet", "d": 1, "core": {"type": "la", "layers": 3,
                                                            "sublayers": 4}},
    "csympnet-la-h2-d2": {"type": "csympnet", "d": 2, "beta_init": -0.3,
                          "core": {"type": "la", "layers": 3, "sublayers": 3, "step_terms": 2}},
    "csympnet-g-d2": {"type": "csympnet", "d": 2, "core": {"type": "g", "layers": 4,
                                                           "width": 5}},
    "sympnet-g-d3": {"type": "sympnet", "d": 3, "core": {"type": "g", "layers": 3, "width": 4}},
    "la-d2": {"type": "la", "d": 2, "layers": 2, "sublayers": 3},
    "g-d1": {"type": "g", "d": 1, "layers": 3, "width": 6},
    "dof-scaled-d3": {"type": "csympnet", "d": 3, "dof_scales": "learned",
                      "core": {"type": "la", "layers": 2, "sublayers": 3}},
    # What `csympnet fit` writes for d > 1: both wrappers around CSympNet-ID.
    "fit-like-d2": {"type": "csympnet", "d": 2, "dof_scales": "learned",
                    "core": {"type": "g", "layers": 4, "width": 6},
                    "normalization": {"q_shift": [0.3, -1.2], "q_scale": [2.0, 0.5],
                                      "p_scale": [0.25, 1.0], "time_scale": 0.7}},
}
STEPS = (0.05, 0.3, 1.0)


def random_module(spec, seed, scale=0.4):
    """The module of `spec` at random parameters (normal, `scale`), β drawn away from 0."""
    rng = np.random.default_rng(seed)
    n = ct.from_spec(spec).n_params
    theta = scale * rng.standard_normal(n)
    module = ct.from_spec(spec, theta)
    if module.gamma is not None:
        beta = [m for m in module.modules() if isinstance(m, ct.CSympNetIDMap)][0].beta
        with torch.no_grad():
            beta.copy_(torch.tensor(rng.uniform(0.05, 0.8) * rng.choice([-1.0, 1.0])))
    return module


def states(d, n, seed):
    return np.random.default_rng(seed).uniform(-1.5, 1.5, size=(n, 2 * d))


@pytest.mark.parametrize("name", sorted(SPECS))
def test_forward_agrees_with_the_library(name, tmp_path):
    """float64 forward = csympnet.load(path).predict on the same file, to 1e-13 of the output's
    size (absolute error over max(1, max |Φ(z)|)), at several h and at per-state steps."""
    module = random_module(SPECS[name], seed=len(name))
    path = tmp_path / "m.json"
    ct.save(module, path)
    model = csympnet.load(path)
    d = model.d
    z = states(d, 40, seed=1)
    hs = list(STEPS) + [np.random.default_rng(2).uniform(0.01, 1.0, size=40)]
    for h in hs:
        ours = module(torch.from_numpy(z), torch.as_tensor(h, dtype=torch.float64)).detach().numpy()
        theirs = model.predict(z, h)
        scale = max(1.0, np.abs(theirs).max())
        assert np.abs(ours - theirs).max() <= 1e-13 * scale, (name, h)
    # A file read back is the same module: θ to the bit, the same spec.
    again = ct.load(path)
    assert torch.equal(again.flat_params(), module.flat_params())
    assert again.spec() == module.spec()
    assert np.array_equal(model.params, module.flat_params().numpy())
    if module.gamma is not None:
        assert float(module.gamma) == pytest.approx(model.gamma, rel=1e-15)


def test_saved_file_round_trips_to_the_byte(tmp_path):
    module = random_module(SPECS["fit-like-d2"], seed=3)
    ct.save(module, tmp_path / "a.json")
    ct.save(ct.load(tmp_path / "a.json"), tmp_path / "b.json", meta={"source": "csympnet.torch"})
    text_a = (tmp_path / "a.json").read_text()
    assert text_a == (tmp_path / "b.json").read_text()
    assert json.loads(text_a)["meta"] == {"source": "csympnet.torch"}


def conformal_residual(module, z, h, factor):
    """max over states of ‖MᵀJM − factor J‖_F / ‖M‖², M = DΦ(z) by autograd (with learned dof
    scales, M = D DΦ D⁻¹, the Jacobian in the unscaled momenta)."""
    d = module.d
    j = torch.zeros(2 * d, 2 * d, dtype=torch.float64)
    j[:d, d:] = torch.eye(d)
    j[d:, :d] = -torch.eye(d)
    # The wrapped CSympNet-ID's Jacobian: with Φ = N⁻¹ D⁻¹ Φ̂ D N (N the normalisation's
    # diagonal diag(1/α, 1/β), D = diag(1, μ) the dof scales), DΦ̂ = (D N) DΦ (D N)⁻¹.
    diag = torch.ones(2 * d, dtype=torch.float64)
    for m in module.modules():
        if isinstance(m, ct.NormalizedMap):
            diag = diag / torch.cat([m.q_scale, m.p_scale])
        if isinstance(m, ct.DofScaledMap):
            diag = diag * torch.cat([torch.ones(d, dtype=torch.float64), m.scales().detach()])
    worst = 0.0
    for row in torch.from_numpy(z):
        m = torch.autograd.functional.jacobian(lambda x: module(x, h), row)
        m = torch.diag(diag) @ m @ torch.diag(1.0 / diag)
        r = m.t() @ j @ m - factor * j
        worst = max(worst, float(r.norm() / m.norm() ** 2))
    return worst


@pytest.mark.parametrize("name", sorted(SPECS))
def test_jacobian_is_exactly_conformally_symplectic(name):
    """DΦᵀ J DΦ = e^{−γ̂ h} J (1 for the symplectic kinds) at random parameters and states, by
    autograd; and the check fails for a wrong factor, so it tests something."""
    for seed in range(3):
        module = random_module(SPECS[name], seed=100 + seed)
        z = states(module.d, 5, seed=seed)
        for h in (0.1, 0.9):
            gamma = 0.0 if module.gamma is None else float(module.gamma)
            factor = np.exp(-gamma * h)
            assert conformal_residual(module, z, h, factor) <= 1e-12, (name, seed, h)
            if gamma > 0:
                assert conformal_residual(module, z, h, factor * 1.05) > 1e-6


def test_parameters_train_on_any_dtype():
    module = ct.CSympNetID(2, core="g:2:4", dof_scales=True, seed=1)
    z = torch.from_numpy(states(2, 16, seed=0))
    loss = (module(z, 0.1) - z).pow(2).sum()
    loss.backward()
    grads = [p.grad for p in module.parameters()]
    assert all(g is not None and torch.isfinite(g).all() for g in grads)
    beta = [m for m in module.modules() if isinstance(m, ct.CSympNetIDMap)][0].beta
    assert float(beta.grad) != 0.0
    module32 = module.to(torch.float32)
    out = module32(z.float(), torch.full((16,), 0.1))
    assert out.dtype == torch.float32 and out.shape == (16, 4)


def test_fresh_module_is_the_architecture_the_library_builds(tmp_path):
    module = ct.CSympNetID(1, core="la:2:3:h2", beta_init=0.2, seed=5)
    assert module.spec() == {"type": "csympnet", "d": 1, "beta_init": 0.2,
                             "core": {"type": "la", "layers": 2, "sublayers": 3, "step_terms": 2}}
    assert float(module.gamma) == 0.2
    theta = module.flat_params()
    core = theta[:-1]  # N(0, 0.01²) matrices and amplitudes, zero biases and step coefficients
    assert 0.0 < float(core.abs().max()) < 0.1
    assert float(theta[-1]) == 0.2 and torch.all(theta[-6:-1] == 0)  # 3 + 2 coefficients
    ct.save(module, tmp_path / "m.json")
    assert csympnet.load(tmp_path / "m.json").n_params == module.n_params


def test_save_keeps_an_existing_file(tmp_path):
    path = tmp_path / "m.json"
    path.write_text("mine")
    module = ct.CSympNetID(1, core="g:2:3")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        ct.save(module, path)
    assert path.read_text() == "mine"
    ct.save(module, path, overwrite=True)
    assert csympnet.load(path).type == "csympnet"


def test_refusals(tmp_path):
    spec = json.dumps({"type": "map", "d": 1, "width": 3})
    _, n = csympnet._core.spec_info(spec)
    csympnet.Model(csympnet._core.from_spec(spec, np.zeros(n), "{}")).save(tmp_path / "map.json")
    with pytest.raises(ValueError, match="model type 'map' has no torch module"):
        ct.load(tmp_path / "map.json")
    good = tmp_path / "good.json"
    ct.save(ct.CSympNetID(1, core="g:2:3"), good)
    text = good.read_text().replace('"beta_init": 0.1', '"beta_init": 0.2')
    (tmp_path / "edited.json").write_text(text)
    with pytest.raises(csympnet.Error, match="checksum mismatch"):
        ct.load(tmp_path / "edited.json")
    with pytest.raises(csympnet.Error, match="unknown key"):
        ct.from_spec({"type": "csympnet", "d": 1, "core": {"type": "la", "layers": 2,
                                                         "sublayers": 2, "width": 3}})
    with pytest.raises(ValueError, match="params: has 3 entries"):
        ct.from_spec(SPECS["g-d1"], np.zeros(3))
    module = ct.CSympNetID(1, core="g:2:3")
    with pytest.raises(ValueError, match=r"z: expected shape \(N, 2\)"):
        module(torch.zeros(4, 3), 0.1)
    with pytest.raises(ValueError, match=r"h: expected a number or a tensor of shape \(4,\)"):
        module(torch.zeros(4, 2), torch.ones(3))
