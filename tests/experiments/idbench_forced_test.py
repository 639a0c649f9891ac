#!/usr/bin/python3
"""Tests of the forced plan of the identification benchmark (experiments/idbench/forced*.py and
its peers): the simulator against closed forms of a driven linear oscillator, ARX on an exactly
ARX system, NARX term selection on a noiseless polynomial NARX system, the multiple-shooting
oracle on a clean forced record, the saturating spring (outside csympnet's library), and
determinism given the seed. Runs under pytest, or as a
plain script (ctest runs it so, needing only /usr/bin/python3 with NumPy and SciPy)."""
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "experiments"))

from idbench import forced  # noqa: E402
from idbench.peers import arx, forced_oracle, narx  # noqa: E402


def _oscillator(w0, gamma, force, h, substeps):
    accel = lambda q, p: -w0 * w0 * q - gamma * p  # noqa: E731
    z = np.zeros((1, 1))
    return forced.simulate(accel, z, z, force[:, None, None], h, substeps)


def test_simulator_matches_the_exact_first_order_hold_response():
    """q'' + gamma q' + w0^2 q = u with u piecewise linear between samples: exact by the
    matrix exponential of the system augmented with u and du/dt"""
    from scipy.linalg import expm
    w0, gamma, h = 1.3, 0.07, 0.21
    rng = np.random.default_rng(3)
    u = rng.standard_normal(300)
    Q, P = _oscillator(w0, gamma, u, h, 20)
    A = np.array([[0, 1, 0, 0], [-w0 * w0, -gamma, 1, 0], [0, 0, 0, 1], [0, 0, 0, 0.0]])
    x = np.zeros(2)
    for k in range(u.size - 1):
        z = expm(A * h) @ np.array([x[0], x[1], u[k], (u[k + 1] - u[k]) / h])
        x = z[:2]
        assert abs(Q[k + 1, 0, 0] - x[0]) < 1e-8 and abs(P[k + 1, 0, 0] - x[1]) < 1e-8, k


def test_simulator_steady_state_amplitude_and_phase_of_a_driven_oscillator():
    w0, gamma, W, h = 1.0, 0.5, 1.4, 2 * math.pi / 1.4 / 400  # 400 samples per forcing period
    t = h * np.arange(int(60 / h))
    Q, _ = _oscillator(w0, gamma, np.sin(W * t), h, 1)
    H = 1.0 / (w0 * w0 - W * W + 1j * gamma * W)
    tail = t > 45.0  # the transient has decayed by exp(-gamma t / 2) < 2e-5
    X = np.column_stack([np.sin(W * t[tail]), np.cos(W * t[tail])])
    a, b = np.linalg.lstsq(X, Q[tail, 0, 0], rcond=None)[0]
    amp, phase = math.hypot(a, b), math.atan2(b, a)
    assert abs(amp / abs(H) - 1) < 1e-4, (amp, abs(H))
    assert abs(phase - np.angle(H)) < 1e-4, (phase, np.angle(H))


def test_arx_recovers_an_exactly_arx_system_and_its_orders():
    rng = np.random.default_rng(5)
    n = 3000
    u = rng.standard_normal((n, 1))
    e = 1e-3 * rng.standard_normal((n, 1))  # equation error: the system is exactly ARX
    y = np.zeros((n, 1))
    for t in range(2, n):
        y[t] = 1.5 * y[t - 1] - 0.7 * y[t - 2] + 0.4 * u[t] + 0.25 * u[t - 1] + 0.1 + e[t]
    m = arx.fit_arx(y, u)
    assert (m["na"], m["nb"]) == (2, 2), m
    assert np.allclose(m["coef"][:, 0], [0.1, 1.5, -0.7, 0.4, 0.25], atol=1e-3), m["coef"]
    # its free run against the same system without the equation error
    y0 = np.zeros((n, 1))
    for t in range(2, n):
        y0[t] = 1.5 * y0[t - 1] - 0.7 * y0[t - 2] + 0.4 * u[t] + 0.25 * u[t - 1] + 0.1
    r = arx.free_run(arx.simulate_arx, m, {"q": y0, "u": u, "q_clean": y0})
    assert r["rms"][0] < 2e-3 * y0.std(), r


def test_narx_term_selection_finds_the_true_terms_of_a_noiseless_system():
    rng = np.random.default_rng(7)
    n = 3000
    u = rng.uniform(-1, 1, (n, 1))
    y = np.zeros((n, 1))
    for t in range(2, n):
        y[t] = (0.6 * y[t - 1] - 0.3 * y[t - 2] + 0.8 * u[t - 1] + 0.2 * y[t - 1] ** 2
                - 0.15 * y[t - 1] * u[t - 1] + 0.1 * u[t - 1] ** 3)
    m = narx.fit_narx(y, u, ny_grid=(2,), nu_grid=(2,), degrees=(3,))
    names = set(narx.term_names(m, 1, 1)[0])
    assert names == {"y1(t-1)", "y1(t-2)", "u1(t-1)", "y1(t-1)*y1(t-1)", "y1(t-1)*u1(t-1)",
                     "u1(t-1)*u1(t-1)*u1(t-1)"}, names
    r = arx.free_run(narx.simulate_narx, m, {"q": y, "u": u, "q_clean": y})
    assert r["rms"][0] < 1e-9, r


def test_oracle_recovers_gamma_and_b_of_a_clean_forced_duffing_record():
    recs, info, s = forced.generate_forced({"system": "duffing", "seed": [11, 0]}, True)
    tr = recs["train"]
    # a short, nearly clean record: 600 samples, noise 1e-5 of the positions' spread
    rng = np.random.default_rng(1)
    n = 600
    q = tr["q_clean"][:n] + 1e-5 * tr["q_clean"].std() * rng.standard_normal((n, 1))
    f = forced_oracle.fit(s, tr["t"][:n], q, tr["u"][:n], info["gamma_true"] * 1.2)
    g = info["gamma_true"]
    assert f["ci_low"] <= g <= f["ci_high"], (f["gamma_hat"], f["ci_low"], f["ci_high"], g)
    assert abs(f["gamma_hat"] - g) < 1e-3 * g
    b, se = f["extra"]["B_hat"][0], f["extra"]["B_se"][0]
    assert abs(b - 1.0) < 1.96 * se + 1e-12 and se < 1e-3, (b, se)


def test_the_saturating_spring_is_its_potentials_gradient_and_runs_only_when_named():
    """V = k q^2/2 + f l log cosh(q/l): grad V by central differences of V, the stiffness 1 at
    rest (K) and k far out; the default plan's systems leave it out (it is outside csympnet's
    term library, run with --forced-systems saturating)."""
    s = forced.forced_system("saturating")
    k, f, l = s["theta"]
    V = lambda q: k * q * q / 2 + f * l * np.log(np.cosh(q / l))  # noqa: E731
    q = np.linspace(-1.5, 1.5, 31)[None, :]
    e = 1e-6
    fd = (V(q + e) - V(q - e)) / (2 * e)
    assert np.allclose(s["grad"](q, s["theta"]), fd, rtol=1e-7, atol=1e-9)
    assert abs(s["K"][0, 0] - (k + f / l)) < 1e-12
    far = (s["grad"](np.array([[10.0]]), s["theta"]) - s["grad"](np.array([[9.0]]), s["theta"]))
    assert abs(far[0, 0] - k) < 1e-9
    assert "saturating" not in forced.FORCED_SYSTEMS
    assert "saturating" in forced.FORCED_EXTRA_SYSTEMS
    recs, info, _ = forced.generate_forced({"system": "saturating", "seed": [3, 0]}, True)
    # driven past the saturation: most of the training record beyond |q| = l
    assert np.mean(np.abs(recs["train"]["q_clean"]) > l) > 0.5, info


def test_records_and_peers_are_deterministic_given_the_seed():
    case = {"system": "pendulum", "seed": [4, 400001]}
    a, ia, _ = forced.generate_forced(case, True)
    b, ib, _ = forced.generate_forced(dict(case), True)
    for k in a:
        for col in ("t", "q", "u"):
            assert np.array_equal(a[k][col], b[k][col]), (k, col)
    assert ia == ib
    c, _, _ = forced.generate_forced({"system": "pendulum", "seed": [5, 400001]}, True)
    assert not np.array_equal(a["train"]["q"], c["train"]["q"])
    short = {k: {**r} for k, r in a.items()}
    for k in short:  # a shorter training record keeps this test fast
        short[k] = {c_: v[:700] for c_, v in a[k].items()}
    r1, r2 = narx.narx_peer(short), narx.narx_peer(short)
    assert r1["tests"] == r2["tests"] and r1["extra"] == r2["extra"]


def test_forced_plan_runs_from_the_command_line_and_tabulates_the_peers(tmp_path=None):
    import json
    import subprocess
    import tempfile
    out = os.path.join(str(tmp_path) if tmp_path else tempfile.mkdtemp(), "out")
    script = os.path.join(HERE, "..", "..", "experiments", "identification_benchmark.py")
    r = subprocess.run([sys.executable, script, "--forced-plan", "--quick", "--cases", "1",
                        "--forced-systems", "pendulum", "--only-peers", "--out", out],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    with open(os.path.join(out, "results.json")) as f:
        res = json.load(f)
    (case,) = res["cases"]
    assert case["methods"]["csympnet"]["status"] == "skipped"
    for m in ("oracle", "narx", "arx"):
        t = case["methods"][m]["tests"]
        assert set(t) == {"test-multisine", "test-rising"} and t["test-rising"]["rms"], (m, t)
    assert case["methods"]["oracle"]["covers"] is not None
    with open(os.path.join(out, "cases", case["id"], "train.csv")) as f:
        assert f.readline().strip() == "t,q1,u1"
    with open(os.path.join(out, "summary.md")) as f:
        md = f.read()
    assert "| multisine/pendulum | narx | 1 | 0 |" in md, md


FAKE = """#!/bin/sh
# a stand-in for csympnet: $FAKE_MODE refuse | fit
if [ "$FAKE_MODE" = refuse ]; then
  echo "csympnet: error: $2:1: trajectories header 't,q1,u1' has 3 columns" >&2; exit 1
fi
if [ "$1" = fit ]; then
  mkdir -p "$4"; echo '{}' > "$4/model.json"
  echo '{"gamma_hat": 0.05, "gamma_ci_low": 0.04, "gamma_ci_high": 0.06, "identified": true}' \
    > "$4/report.json"; exit 0
fi
mkdir -p "$9"; echo '{"simulation": {"rmse": [0.001, 0.002]}}' > "$9/report.json"
"""


def test_csympnet_forced_reads_the_contract_and_records_a_refusal_as_unsupported(tmp_path=None):
    import tempfile
    from idbench.peers.csympnet import run_csympnet_forced
    tmp = str(tmp_path) if tmp_path else tempfile.mkdtemp()
    exe = os.path.join(tmp, "fake-csympnet")
    with open(exe, "w") as f:
        f.write(FAKE)
    os.chmod(exe, 0o755)
    tests = {"test-multisine": os.path.join(tmp, "ms.csv")}
    os.environ["FAKE_MODE"] = "refuse"
    r = run_csympnet_forced(exe, os.path.join(tmp, "tr.csv"), tests, os.path.join(tmp, "o1"),
                            [], 60, 100)
    assert r["status"] == "unsupported" and "header" in r["reason"] and r["tests"] == {}, r
    os.environ["FAKE_MODE"] = "fit"
    r = run_csympnet_forced(exe, os.path.join(tmp, "tr.csv"), tests, os.path.join(tmp, "o2"),
                            [], 60, 100)
    del os.environ["FAKE_MODE"]
    assert r["status"] == "ok" and r["gamma_hat"] == 0.05 and r["ci_high"] == 0.06, r
    t = r["tests"]["test-multisine"]
    assert t["status"] == "ok" and t["rms"] == [0.001, 0.002], t
    assert t["command"][t["command"].index("--warmup") + 1] == "100"


def test_forced_long_record_writes_the_asked_samples_and_refuses_to_overwrite(tmp_path=None):
    """experiments/forced_long_record.py: a short record of the same kind, its truth beside it,
    the same bits for the same seed, and an existing file left alone"""
    import json
    import subprocess
    import tempfile
    tmp = str(tmp_path) if tmp_path else tempfile.mkdtemp()
    script = os.path.join(HERE, "..", "..", "experiments", "forced_long_record.py")
    outs = [os.path.join(tmp, n) for n in ("a.csv", "b.csv")]
    for out in outs:
        r = subprocess.run(["/usr/bin/python3", script, "--out", out, "--samples", "600",
                            "--period", "256", "--seed", "4"], capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    with open(outs[0]) as f:
        lines = f.read().splitlines()
    assert lines[0] == "t,q1,u1" and len(lines) == 601, (lines[0], len(lines))
    with open(outs[1]) as f:
        assert f.read().splitlines() == lines
    with open(outs[0] + ".json") as f:
        truth = json.load(f)
    assert truth["samples"] == 600 and truth["system"] == "duffing" and truth["gamma"] > 0
    r = subprocess.run(["/usr/bin/python3", script, "--out", outs[0], "--samples", "600",
                        "--period", "256"], capture_output=True, text=True)
    assert r.returncode != 0 and "exists" in r.stderr, r.stderr
    with open(outs[0]) as f:
        assert f.read().splitlines() == lines


if __name__ == "__main__":
    from script_tests import run
    run(globals())
