"""Model.score on positions alone: the same scores as `csympnet evaluate --data positions.csv`,
to the bit (one C++ function, diagnostics/positions_score.hpp), and the same refusals."""

import json

import numpy as np
import pytest

import csympnet

# Two coupled damped oscillators (d = 2) as a Hamiltonian-library csympnet model:
# θ = W (lower triangle), the coefficients of q1², q2², (q1 − q2)², β.
SPEC = {"type": "csympnet", "d": 2,
        "core": {"type": "library", "terms": ["q1^2", "q2^2", "(q1-q2)^2"], "order": 4}}
THETA = np.array([1.0, 0.0, 1.0, 0.5, 0.8, 0.3, 0.15])


def model(theta=THETA):
    return csympnet.Model(csympnet._core.from_spec(json.dumps(SPEC), theta, "{}"))


@pytest.fixture(scope="module")
def record():
    """Two noisy trajectories of the model's own motion at irregular times: (t, q, traj)."""
    m, rng = model(), np.random.default_rng(7)
    ts, qs, labels = [], [], []
    for k, (n, z0) in enumerate([(90, [1.0, -0.5, 0.2, 0.4]), (60, [0.3, 0.8, -0.6, 0.0])]):
        t = np.cumsum(np.concatenate([[0.0], rng.uniform(0.05, 0.12, n - 1)]))
        z = m.rollout(np.array(z0), np.diff(t))
        ts.append(t)
        qs.append(z[:, :2] + 0.005 * rng.standard_normal((n, 2)))
        labels.append(np.full(n, k))
    return np.concatenate(ts), np.concatenate(qs), np.concatenate(labels)


def write_positions(path, t, q, traj):
    with open(path, "w") as f:
        f.write("traj,t,q1,q2\n")
        for k, tk, row in zip(traj, t, q):
            f.write(f"{k},{tk!r},{row[0]!r},{row[1]!r}\n")  # repr: the same doubles back


@pytest.mark.parametrize("warmup", [None, 15])
def test_cli_and_python_agree_to_the_bit(tmp_path, run_cli, record, warmup):
    t, q, traj = record
    m = model()
    m.save(tmp_path / "model.json")
    write_positions(tmp_path / "pos.csv", t, q, traj)
    args = ["evaluate", "--model", tmp_path / "model.json", "--data", tmp_path / "pos.csv"]
    if warmup is not None:
        args += ["--warmup", warmup]
    report = json.loads(run_cli(*args).stdout)
    py = m.score(q, t, traj, warmup=warmup)
    rollouts = py.pop("rollouts")
    assert py == report["positions"]  # every number, to the bit
    assert "observed" not in report
    assert report["test_trajectories"] == 2
    per = py["per_trajectory"]
    expected = [10, 10] if warmup is None else [15, 15]  # a tenth of 90 and 60, at least 10
    assert [p["warmup"] for p in per] == expected
    assert [p["scored"] for p in per] == [90 - expected[0], 60 - expected[1]]
    assert py["samples_scored"] == 150 - sum(expected)
    assert py["warmup"] == warmup
    assert [r.shape for r in rollouts] == [(p["scored"] + 1, 4) for p in per]
    # The true model forecasts noise of 0.005 to about the noise.
    assert 0.003 < py["rmse"] < 0.01
    assert len(py["rmse_per_coordinate"]) == 2
    assert py["nrmse"] < 0.05


def test_positions_are_told_apart_from_states_by_the_models_d(record):
    t, q, traj = record
    m = model()
    auto = m.score(q, t, traj)
    explicit = m.score(q, t, traj, observed="positions")
    assert auto["rmse"] == explicit["rmse"]
    # Lists of arrays, one per trajectory, are the same record.
    sel = [traj == k for k in (0, 1)]
    listed = m.score([q[s] for s in sel], [t[s] for s in sel])
    assert listed["rmse"] == auto["rmse"]
    with pytest.raises(ValueError, match="2d = 4"):
        m.score(q, t, traj, observed="states")
    with pytest.raises(ValueError, match="warmup"):
        m.score(np.hstack([q, q]), t, traj, warmup=10)
    with pytest.raises(ValueError, match="observed"):
        m.score(q, t, traj, observed="momenta")


def test_a_wrong_damping_rate_scores_worse(record):
    t, q, traj = record
    good = model().score(q, t, traj, warmup=10)["rmse"]
    theta = THETA.copy()
    theta[-1] = 0.4
    assert model(theta).score(q, t, traj, warmup=10)["rmse"] > 3 * good


def test_hostile_positions_are_refused(tmp_path, run_cli, record):
    t, q, traj = record
    m = model()
    m.save(tmp_path / "model.json")
    # Too short for the default warm-up: both front ends name the warm-up.
    with pytest.raises(csympnet.Error, match="warmup: data: trajectory 1 of 1 has 8 samples"):
        m.score(q[:8], t[:8])
    write_positions(tmp_path / "short.csv", t[:8], q[:8], traj[:8])
    p = run_cli("evaluate", "--model", tmp_path / "model.json", "--data", tmp_path / "short.csv",
                check=False)
    assert p.returncode == 1 and "--warmup" in p.stderr and "8 samples" in p.stderr
    for bad in (0, 2, 90):
        with pytest.raises(csympnet.Error, match="warmup"):
            m.score(q[traj == 0], t[traj == 0], warmup=bad)
    with pytest.raises(TypeError, match="warmup"):
        m.score(q, t, traj, warmup=10.5)
    nan = q.copy()
    nan[40, 1] = np.nan
    with pytest.raises(ValueError, match="finite"):
        m.score(nan, t, traj)
