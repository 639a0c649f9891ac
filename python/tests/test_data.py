"""Presets, systems, generation (identical to `csympnet generate`) and CSV files."""

import numpy as np
import pytest

import csympnet


def test_presets_match_the_protocol():
    s = csympnet.systems
    assert sorted(s) == sorted(["s1", "s2", "s3", "s2-100", "s3-100"])
    assert s["s1"]["system"]["kind"] == "oscillator" and s["s1"]["system"]["d"] == 1
    assert s["s2"]["system"]["kind"] == "chain" and s["s2"]["system"]["d"] == 10
    assert s["s3-100"]["system"]["alpha"] == 1e-4
    assert all(p["system"]["gamma"] == 0.05 and p["h_test"] == 0.2 for p in s.values())
    assert (s["s1"]["n_train"], s["s1"]["n_val"]) == (80, 20)
    assert s["s1"]["train_steps"] == {"h_min": 0.05, "h_max": 0.15}
    assert csympnet.model_types()[:2] == ["csympnet", "sympnet"]


def test_generate_shapes_and_ranges():
    tr = csympnet.generate("s1", "train")
    assert tr.z0.shape == tr.z1.shape == (80, 2) and tr.h.shape == (80,)
    assert np.all((tr.h >= 0.05) & (tr.h <= 0.15)) and np.all(np.abs(tr.z0) <= 1)
    assert csympnet.generate("s2", "val").z0.shape == (100, 20)
    tests = csympnet.generate("s1", "test")
    assert len(tests) == 10 and tests[0].z.shape == (51, 2)
    np.testing.assert_allclose(tests[0].t, 0.2 * np.arange(51), atol=1e-12)
    small = csympnet.generate("s1", "train", n=5, h=0.1, system={"gamma": 0.2})
    assert small.z0.shape == (5, 2) and np.all(small.h == 0.1)


@pytest.mark.parametrize("split, args", [("train", []), ("val", ["--sigma", "0.01"]),
                                         ("test", ["--seed", "3", "--n", "2"])])
def test_generate_equals_cli_generate(tmp_path, run_cli, split, args):
    path = tmp_path / f"{split}.csv"
    run_cli("generate", "--preset", "s3", "--split", split, "--gamma", "0.1", *args,
            "--out", path)
    cli = csympnet.read_csv(path)
    kwargs = {"system": {"gamma": 0.1}}
    if split == "val":
        kwargs["sigma"] = 0.01
    if split == "test":
        kwargs.update(seed=3, n=2)
    py = csympnet.generate("s3", split, **kwargs)
    if split == "test":
        assert len(cli) == len(py) == 2
        for a, b in zip(cli, py):
            assert np.array_equal(a.t, b.t) and np.array_equal(a.z, b.z)
    else:
        assert all(np.array_equal(a, b) for a, b in zip(cli, py))
        # An independent parser reads the same numbers.
        table = np.loadtxt(path, delimiter=",", skiprows=1)
        assert np.array_equal(table[:, 0], py.h) and np.array_equal(table[:, 1:21], py.z0)


def test_noise_changes_only_with_sigma():
    clean = csympnet.generate("s1", "train")
    noisy = csympnet.generate("s1", "train", sigma=1e-2)
    assert not np.array_equal(clean.z0, noisy.z0)
    assert np.array_equal(clean.h, noisy.h)
    rel = np.std(noisy.z0 - clean.z0, axis=0) / np.std(clean.z0, axis=0)
    assert np.all((rel > 0.005) & (rel < 0.02))


def test_flow_against_the_exact_damped_oscillator():
    gamma, w = 0.3, 1.5
    system = csympnet.System(kind="oscillator", d=1, gamma=gamma, omega=w)
    z0 = np.array([[0.7, -0.4], [-1.0, 0.2]])
    h = 0.8
    # q'' + γq' + ω²q = 0, underdamped: q = e^{−γt/2}(A cos νt + B sin νt).
    nu = np.sqrt(w ** 2 - gamma ** 2 / 4)
    q0, p0 = z0[:, 0], z0[:, 1]
    a, b = q0, (p0 + gamma / 2 * q0) / nu
    e = np.exp(-gamma * h / 2)
    q = e * (a * np.cos(nu * h) + b * np.sin(nu * h))
    p = e * (-gamma / 2 * (a * np.cos(nu * h) + b * np.sin(nu * h))
             + nu * (-a * np.sin(nu * h) + b * np.cos(nu * h)))
    exact = np.c_[q, p]
    np.testing.assert_allclose(system.flow(z0, h, reference="expm"), exact, atol=1e-13)
    np.testing.assert_allclose(system.flow(z0, h, reference="rk"), exact, atol=1e-10)
    np.testing.assert_allclose(system.flow(z0, h), exact, atol=1e-6)  # 2nd order, δ = 1e-3
    assert system.flow(z0[0], h).shape == (2,)


def test_system_energy_and_field():
    system = csympnet.System(kind="cubic", d=2, gamma=0.1, omega=2.0, alpha=0.5)
    z = np.array([0.3, -0.2, 0.5, 0.1])
    q, p = z[:2], z[2:]
    assert system.energy(z)[0] == pytest.approx(0.5 * p @ p + 2.0 * q @ q + 0.5 * q.sum() ** 3)
    f = system.vector_field(z)
    np.testing.assert_allclose(f[:2], p)
    np.testing.assert_allclose(f[2:], -(4.0 * q + 1.5 * q.sum() ** 2) - 0.1 * p)
    assert repr(system).startswith("csympnet.System(kind='cubic'")


def test_csv_round_trip(tmp_path):
    pairs = csympnet.generate("s1", "train", n=7)
    csympnet.write_csv(tmp_path / "p.csv", pairs)
    back = csympnet.read_csv(tmp_path / "p.csv")
    assert isinstance(back, csympnet.Pairs)
    assert all(np.array_equal(a, b) for a, b in zip(back, pairs))
    trajs = csympnet.generate("s1", "test", n=2)
    csympnet.write_csv(tmp_path / "t.csv", trajs)
    back = csympnet.read_csv(tmp_path / "t.csv")
    assert all(np.array_equal(a.z, b.z) and np.array_equal(a.t, b.t) for a, b in zip(back, trajs))
    (tmp_path / "bad.csv").write_text("h,q1,p1,next_q1,next_p1\n0.1,1,2,x,4\n")
    with pytest.raises(csympnet.Error, match="bad.csv:2"):
        csympnet.read_csv(tmp_path / "bad.csv")
