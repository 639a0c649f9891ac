"""experiments/cost_scaling.py: the record's closed form solves its ODE (central differences),
the oracle covers gamma at its level on noisy records, every length decays by the same factor,
the log-log slope is read over N >= 10^4, and the script runs from the command line with a
stand-in for csympnet."""
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

import cost_scaling as cs  # noqa: E402


def test_the_closed_form_solves_the_oscillator():
    rng = np.random.default_rng(3)
    for _ in range(5):
        omega, gamma = rng.uniform(0.5, 5), rng.uniform(0.001, 0.5)
        q0, v0 = rng.normal(), rng.normal()
        t = np.linspace(0.1, 20, 57)
        eps = 1e-4
        q, v = cs.exact(t, omega, gamma, q0, v0)
        qp, vp = cs.exact(t + eps, omega, gamma, q0, v0)
        qm, vm = cs.exact(t - eps, omega, gamma, q0, v0)
        assert np.max(np.abs((qp - qm) / (2 * eps) - v)) < 1e-6
        acc = (vp - vm) / (2 * eps)
        assert np.max(np.abs(acc + omega ** 2 * q + gamma * v)) < 1e-5
        q00, v00 = cs.exact(np.zeros(1), omega, gamma, q0, v0)
        assert abs(q00[0] - q0) < 1e-14 and abs(v00[0] - v0) < 1e-13


def test_every_length_decays_by_the_same_factor():
    for n in (1000, 31623):
        tr = cs.truth_for(n)
        assert abs(0.5 * tr["gamma"] * n * tr["h"] - 2.0) < 1e-12


def test_the_oracle_covers_gamma_at_its_level():
    covered, trials = 0, 40
    for seed in range(trials):
        t, q, p, tr = cs.record(2000, seed, momenta=seed % 2 == 0)
        o = cs.oracle(t, q, p, tr, seed)
        covered += o["ci_low"] <= tr["gamma"] <= o["ci_high"]
        assert abs(o["gamma_hat"] - tr["gamma"]) < 0.05 * tr["gamma"]
    # 40 draws of a 95% interval: 35 or fewer covers happen with probability 0.05
    assert covered >= 35, covered


def test_the_slope_is_read_over_the_long_records():
    rows = [{"n": n, "c": 2e-4 * n ** 1.3} for n in (1000, 10000, 100000, 1000000)]
    rows[0]["c"] = 50.0  # a short record's fixed cost does not enter
    assert abs(cs.slope(rows, "c") - 1.3) < 1e-9
    assert cs.slope(rows[:2], "c") is None


def test_runs_from_the_command_line_with_a_stand_in():
    tmp = tempfile.mkdtemp()
    stand_in = os.path.join(tmp, "fake-csympnet")
    with open(stand_in, "w") as f:
        f.write("#!/usr/bin/python3\nimport json, os, sys\nout = sys.argv[sys.argv.index('--out') + 1]\n"
                "os.makedirs(out, exist_ok=True)\njson.dump({'gamma_hat': 0.08, 'gamma_ci_low': 0.07, "
                "'gamma_ci_high': 0.09, 'identified': True, 'verdict': 'identified'}, "
                "open(os.path.join(out, 'report.json'), 'w'))\n")
    os.chmod(stand_in, 0o755)
    out = os.path.join(tmp, "out")
    r = subprocess.run([sys.executable, os.path.join(EXPERIMENTS, "cost_scaling.py"), "--out", out,
                        "--csympnet", stand_in, "--lengths", "1000,2000"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    res = json.load(open(os.path.join(out, "results.json")))
    assert [(row["observed"], row["n"]) for row in res["rows"]] == [
        ("momenta", 1000), ("momenta", 2000), ("positions", 1000), ("positions", 2000)]
    row = res["rows"][0]
    assert row["csympnet"]["status"] == "ok" and row["csympnet"]["covers"] is True
    assert math.isfinite(row["oracle"]["cpu_seconds"])
    header = open(os.path.join(out, "positions-1000", "record.csv")).readline().strip()
    assert header == "t,q1"
    bad = subprocess.run([sys.executable, os.path.join(EXPERIMENTS, "cost_scaling.py"), "--out",
                          out, "--csympnet", stand_in, "--lengths", "1000,x"],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "--lengths" in bad.stderr


if __name__ == "__main__":
    from script_tests import run
    run(globals())
