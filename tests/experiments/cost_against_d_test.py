"""experiments/cost_against_d.py: the chain's closed form solves its ODE (central differences)
at random d, stiffness and damping; the modes are orthonormal eigenvectors of the chain's
matrix; the oracle covers gamma at its level on noisy records; every d decays by the same
factor; and the script runs from the command line with a stand-in for csympnet."""
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
EXPERIMENTS = os.path.join(HERE, "..", "..", "experiments")
sys.path.insert(0, EXPERIMENTS)

import cost_against_d as cd  # noqa: E402


def chain_matrix(d):
    return 2.0 * np.eye(d) - np.eye(d, k=1) - np.eye(d, k=-1)


def test_the_modes_diagonalise_the_chain():
    for d in (1, 2, 5, 13):
        shapes, lam = cd.modes(d)
        assert np.max(np.abs(shapes.T @ shapes - np.eye(d))) < 1e-12
        assert np.max(np.abs(chain_matrix(d) @ shapes - shapes * lam)) < 1e-12


def test_the_closed_form_solves_the_chain():
    rng = np.random.default_rng(5)
    for _ in range(5):
        d = int(rng.integers(1, 9))
        k, gamma = rng.uniform(0.5, 3.0), rng.uniform(0.001, 0.3)
        shapes, lam = cd.modes(d)
        eta0, v0 = rng.normal(size=d), rng.normal(size=d)
        t = np.linspace(0.1, 15, 41)
        eps = 1e-4
        q, v = cd.solution(t, k, gamma, eta0, v0, shapes, lam)
        qp, vp = cd.solution(t + eps, k, gamma, eta0, v0, shapes, lam)
        qm, vm = cd.solution(t - eps, k, gamma, eta0, v0, shapes, lam)
        assert np.max(np.abs((qp - qm) / (2 * eps) - v)) < 1e-6
        acc = (vp - vm) / (2 * eps)
        assert np.max(np.abs(acc + k * q @ chain_matrix(d).T + gamma * v)) < 1e-5
        q00, v00 = cd.solution(np.zeros(1), k, gamma, eta0, v0, shapes, lam)
        assert np.max(np.abs(q00[0] - shapes @ eta0)) < 1e-13
        assert np.max(np.abs(v00[0] - shapes @ v0)) < 1e-13


def test_every_d_decays_by_the_same_factor():
    for d in (1, 7, 20):
        tr = cd.truth_for(d, 3200)
        assert abs(0.5 * tr["gamma"] * 3200 * tr["h"] - 2.0) < 1e-12


def test_the_oracle_covers_gamma_at_its_level():
    covered, trials = 0, 40
    for seed in range(trials):
        d = 1 + seed % 4
        t, q, p, tr = cd.record(d, 600, seed, momenta=seed % 2 == 0)
        o = cd.oracle(t, q, p, tr, seed)
        covered += o["ci_low"] <= tr["gamma"] <= o["ci_high"]
        assert abs(o["gamma_hat"] - tr["gamma"]) < 0.05 * tr["gamma"]
    # 40 draws of a 95% interval: 35 or fewer covers happen with probability 0.05
    assert covered >= 35, covered


def test_runs_from_the_command_line_with_a_stand_in():
    tmp = tempfile.mkdtemp()
    stand_in = os.path.join(tmp, "fake-csympnet")
    with open(stand_in, "w") as f:
        f.write("#!/usr/bin/python3\nimport json, os, sys\nout = sys.argv[sys.argv.index('--out') + 1]\n"
                "assert '--core' in sys.argv\n"
                "os.makedirs(out, exist_ok=True)\njson.dump({'gamma_hat': 0.08, 'gamma_ci_low': 0.07, "
                "'gamma_ci_high': 0.09, 'identified': True, 'verdict': 'identified'}, "
                "open(os.path.join(out, 'report.json'), 'w'))\n")
    os.chmod(stand_in, 0o755)
    out = os.path.join(tmp, "out")
    r = subprocess.run([sys.executable, os.path.join(EXPERIMENTS, "cost_against_d.py"), "--out",
                        out, "--csympnet", stand_in, "--dims", "1,3", "--samples", "300",
                        "--fit-args", "--core library"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    res = json.load(open(os.path.join(out, "results.json")))
    assert [(row["observed"], row["d"]) for row in res["rows"]] == [
        ("momenta", 1), ("momenta", 3), ("positions", 1), ("positions", 3)]
    assert res["config"]["fit_args"] == ["--core", "library"]
    row = res["rows"][0]
    assert row["csympnet"]["status"] == "ok" and row["csympnet"]["covers"] is False
    assert math.isfinite(row["oracle"]["cpu_seconds"])
    header = open(os.path.join(out, "positions-d3", "record.csv")).readline().strip()
    assert header == "t,q1,q2,q3"
    header = open(os.path.join(out, "momenta-d3", "record.csv")).readline().strip()
    assert header == "t,q1,q2,q3,p1,p2,p3"
    bad = subprocess.run([sys.executable, os.path.join(EXPERIMENTS, "cost_against_d.py"), "--out",
                          out, "--csympnet", stand_in, "--dims", "1,x"],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "--dims" in bad.stderr


if __name__ == "__main__":
    from script_tests import run
    run(globals())
