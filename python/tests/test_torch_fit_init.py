"""The user story of csympnet.torch: train CSympNet-ID in PyTorch on noisy trajectories of a damped
oscillator, save it, and let `csympnet fit --init` refine it and give γ̂ its interval."""

import json
import subprocess

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import csympnet  # noqa: E402
import csympnet.torch as ct  # noqa: E402

GAMMA = 0.1
SYSTEM = {"kind": "oscillator", "d": 1, "gamma": GAMMA, "omega": 1.0}
NOISE = 0.01  # standard deviation of the observation noise, in the states' units


def trajectories(n, seed, noise):
    """n trajectories of 51 points (step 0.2) from random starts, with Gaussian noise."""
    tests = csympnet.generate("s1", "test", n=n, seed=seed, system=SYSTEM)
    rng = np.random.default_rng(seed)
    return [csympnet.Trajectory(tr.t, tr.z + noise * rng.standard_normal(tr.z.shape))
            for tr in tests]


def one_step_rmse(predict, trajs):
    errs = [predict(tr.z[:-1], np.diff(tr.t)) - tr.z[1:] for tr in trajs]
    return float(np.sqrt(np.mean(np.concatenate(errs) ** 2)))


def train_in_torch(trajs, steps=300):
    z0 = torch.from_numpy(np.concatenate([tr.z[:-1] for tr in trajs]))
    z1 = torch.from_numpy(np.concatenate([tr.z[1:] for tr in trajs]))
    h = torch.from_numpy(np.concatenate([np.diff(tr.t) for tr in trajs]))
    net = ct.CSympNetID(1, core="la:3:4", beta_init=0.5, seed=0)
    opt = torch.optim.Adam(net.parameters(), lr=1e-2)
    for _ in range(steps):
        opt.zero_grad()
        loss = (net(z0, h) - z1).pow(2).sum(dim=1).mean()
        loss.backward()
        opt.step()
    return net


def test_torch_model_refined_by_fit_init(tmp_path, cli):
    data = trajectories(12, seed=7, noise=NOISE)
    held_out = trajectories(6, seed=8, noise=0.0)
    csympnet.write_csv(tmp_path / "data.csv", data)
    net = train_in_torch(data)
    ct.save(net, tmp_path / "torch.json")

    out = tmp_path / "fit"
    p = subprocess.run([cli, "fit", str(tmp_path / "data.csv"), "--init",
                        str(tmp_path / "torch.json"), "--lm-iterations", "60", "--out", str(out),
                        "-q"], capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    report = json.loads((out / "report.json").read_text())
    file_checksum = json.loads((tmp_path / "torch.json").read_text())["checksum"]
    assert report["init"] == {"file": str(tmp_path / "torch.json"), "checksum": file_checksum}
    assert report["choices"]["epochs"] == 0  # LM alone, from the torch θ
    assert report["identified"], report["reasons"]
    low, high = report["gamma_ci_low"], report["gamma_ci_high"]
    assert 0.0 < low < GAMMA < high < 2 * GAMMA
    # The torch model had no normalisation, so neither has the refined one: the same units.
    assert "normalization" not in report["architecture"]

    refined = csympnet.load(out / "model.json")
    assert refined.gamma == pytest.approx(report["gamma_hat"], rel=1e-15)
    before = one_step_rmse(lambda z, h: net(torch.from_numpy(z), torch.from_numpy(h))
                           .detach().numpy(), held_out)
    after = one_step_rmse(refined.predict, held_out)
    assert after < 0.8 * before, (before, after)
    # Python's identify(init=) is the same fit, to the bit.
    result = csympnet.identify([tr.z for tr in data], [tr.t for tr in data],
                               init=tmp_path / "torch.json", lm_iterations=60)
    assert result.gamma == report["gamma_hat"]
    assert result.report["init"]["checksum"] == file_checksum
    est = csympnet.CSympNetID(init=tmp_path / "torch.json", lm_iterations=60)
    assert est.fit([tr.z for tr in data], [tr.t for tr in data]).gamma_ == report["gamma_hat"]
    # The refined file is again a torch module, which predicts as the library does.
    again = ct.load(out / "model.json")
    z = held_out[0].z
    assert np.abs(again(torch.from_numpy(z), 0.2).detach().numpy()
                  - refined.predict(z, 0.2)).max() < 1e-13


def test_fit_init_refusals(tmp_path, run_cli, s1_pairs):
    data = trajectories(4, seed=1, noise=0.0)
    csympnet.write_csv(tmp_path / "data.csv", data)
    ct.save(ct.CSympNetID(2, core="g:2:3"), tmp_path / "d2.json")
    p = run_cli("fit", tmp_path / "data.csv", "--init", tmp_path / "d2.json", "--out",
                tmp_path / "a", check=False)
    assert p.returncode == 1
    assert "--init" in p.stderr and "d2.json is a model of d = 2" in p.stderr
    sympnet = ct.from_spec({"type": "sympnet", "d": 1, "core": {"type": "g", "layers": 2,
                                                              "width": 3}})
    ct.save(sympnet, tmp_path / "sympnet.json")
    p = run_cli("fit", tmp_path / "data.csv", "--init", tmp_path / "sympnet.json", "--out",
                tmp_path / "b", check=False)
    assert p.returncode == 2
    assert "--init" in p.stderr and "type 'sympnet'" in p.stderr
    one = tmp_path / "d1.json"
    ct.save(ct.CSympNetID(1, core="g:2:3"), one)
    p = run_cli("fit", tmp_path / "data.csv", "--init", one, "--core", "la:2:2", "--out",
                tmp_path / "c", check=False)
    assert p.returncode == 2 and "--core" in p.stderr and "fixes the core" in p.stderr
    p = run_cli("fit", tmp_path / "data.csv", "--init", one, "--recipe", "classic", "--out",
                tmp_path / "d", check=False)
    assert p.returncode == 2 and "--init" in p.stderr
    normalised = ct.CSympNetID(1, core="g:2:3", normalization={
        "q_shift": [0.0], "q_scale": [1.0], "p_scale": [1.0], "time_scale": 0.2})
    ct.save(normalised, tmp_path / "n.json")
    p = run_cli("fit", tmp_path / "data.csv", "--init", tmp_path / "n.json", "--no-normalize",
                "--out", tmp_path / "e", check=False)
    assert p.returncode == 2 and "--no-normalize" in p.stderr
    with pytest.raises(csympnet.Error, match="init: .*sympnet.json: a model of type 'sympnet'"):
        csympnet.identify([tr.z for tr in data], [tr.t for tr in data],
                          init=tmp_path / "sympnet.json")


def test_fit_init_keeps_the_units_of_a_fit_model(tmp_path, run_cli):
    """A `fit` model carries its normalisation; refined with --init it keeps it (θ is in those
    units), whatever the new data's spread; --epochs runs AdamW from the file's θ first."""
    data = trajectories(8, seed=3, noise=NOISE)
    csympnet.write_csv(tmp_path / "data.csv", data)
    run_cli("fit", tmp_path / "data.csv", "--core", "g:2:4", "--epochs", "50",
            "--lm-iterations", "3", "--out", tmp_path / "first", "-q", check=False)
    first = json.loads((tmp_path / "first" / "report.json").read_text())
    scaled = [csympnet.Trajectory(tr.t, 3.0 * tr.z) for tr in data]  # another spread
    csympnet.write_csv(tmp_path / "scaled.csv", scaled)
    run_cli("fit", tmp_path / "scaled.csv", "--init", tmp_path / "first" / "model.json",
            "--epochs", "20", "--lm-iterations", "3", "--out", tmp_path / "second", "-q",
            check=False)
    second = json.loads((tmp_path / "second" / "report.json").read_text())
    assert second["normalization"] == first["normalization"]
    assert second["architecture"] == first["architecture"]
    assert second["choices"]["epochs"] == 20 and second["training"]["epochs_run"] > 0
    assert second["init"]["file"] == str(tmp_path / "first" / "model.json")
