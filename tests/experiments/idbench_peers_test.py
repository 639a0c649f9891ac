#!/usr/bin/python3
"""Tests of the identification benchmark's peers (experiments/idbench/): the textbook fits and
the whole-record oracles recover gamma on clean simulated records, the closed-form chain
positions match the matrix exponential, the observed plan's records are reproducible, the
one-coordinate RK4 gives the array RK4's bits, and the CPU seconds of a child are measured. Runs under pytest, or as a plain script (ctest runs it so,
needing only /usr/bin/python3 with NumPy and SciPy)."""
import math
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "experiments"))

from idbench import linear  # noqa: E402
from idbench.observed import generate_observed, plan_observed  # noqa: E402
from idbench.peers import positions_oracle, textbook  # noqa: E402
from idbench.peers.csympnet import run_child_cpu  # noqa: E402
from idbench.simulation import integrate, rk4, rk4_arrays  # noqa: E402
from idbench.systems import make_system  # noqa: E402


def chain_record(d, gamma, seed, duration=40.0, h=0.04):
    rng = np.random.default_rng(seed)
    k = linear.draw_springs(rng, d)
    t = np.arange(0.0, duration, h)
    q = linear.positions(linear.chain_stiffness(k), gamma, rng.normal(size=d), np.zeros(d), t)
    return t, q, k, rng


def pendulum_record(gamma, amp, n, h, p=False):
    s = make_system("pendulum", np.random.default_rng(0), False)
    Q, P = integrate(s, gamma, np.array([[amp]]), np.array([[0.0]]), np.full((1, n - 1), h), 1e-3)
    return h * np.arange(n), Q[:, 0, 0], P[:, 0, 0], s


def test_chain_positions_and_velocities_match_the_matrix_exponential():
    from scipy.linalg import expm
    rng = np.random.default_rng(4)
    d, gamma = 3, 0.3
    K = linear.chain_stiffness(linear.draw_springs(rng, d))
    q0, v0 = rng.normal(size=d), rng.normal(size=d)
    t = np.array([0.0, 0.37, 2.5, 11.0])
    A = np.block([[np.zeros((d, d)), np.eye(d)], [-K, -gamma * np.eye(d)]])
    ref = np.stack([(expm(A * s) @ np.concatenate([q0, v0]))[:d] for s in t])
    assert np.abs(linear.positions(K, gamma, q0, v0, t) - ref).max() < 1e-12
    ref_v = np.stack([(expm(A * s) @ np.concatenate([q0, v0]))[d:] for s in t])
    assert np.abs(linear.velocities(K, gamma, q0, v0, t) - ref_v).max() < 1e-11


def test_textbook_damped_sinusoids_recover_gamma_on_a_clean_record_in_pixels():
    for d, gamma in ((1, 0.08), (2, 0.15)):
        t, q, k, _ = chain_record(d, gamma, seed=d)
        px = 120.0 * q + 300.0
        w = np.sqrt(np.linalg.eigvalsh(linear.chain_stiffness(k)))
        r = textbook.damped_sinusoids(t, px, 1.15 * gamma, w)
        assert abs(r["gamma_hat"] - gamma) < 1e-8 * gamma, (d, r)
        assert r["ci_low"] <= gamma <= r["ci_high"]


def test_log_decrement_recovers_gamma_of_one_mode():
    t, q, _, rng = chain_record(1, 0.05, seed=7, duration=200.0, h=0.01)
    r = textbook.log_decrement(t, 50.0 * q[:, 0] + 7.0 + 1e-4 * rng.normal(size=t.size))
    assert abs(r["gamma_hat"] - 0.05) < 2e-3 * 0.05, r
    assert r["extra"]["extremes"] >= 50


def test_positions_oracle_recovers_gamma_of_a_linear_chain():
    t, q, k, rng = chain_record(3, 0.12, seed=3)
    r = positions_oracle.linear(t, q, k, 0.12 * 1.2)
    assert abs(r["gamma_hat"] - 0.12) < 1e-10, r
    # with noise of 0.2% of each coordinate's spread, over 8 records: estimates near the truth,
    # and the interval covers on most
    covered = 0
    for seed in range(8):
        t, q, k, rng = chain_record(2, 0.1, seed=100 + seed)
        qn = q + 2e-3 * q.std(axis=0) * rng.normal(size=q.shape)
        r = positions_oracle.linear(t, qn, k, 0.11)
        assert abs(r["gamma_hat"] - 0.1) < 0.01, r
        covered += r["ci_low"] <= 0.1 <= r["ci_high"]
    assert covered >= 6, covered


def test_positions_oracle_recovers_gamma_of_a_pendulum_from_positions_and_from_q_and_p():
    t, q, p, s = pendulum_record(0.05, 1.0, 700, 2 * math.pi / 40)
    r = positions_oracle.nonlinear(t, q, s, 0.06)
    assert abs(r["gamma_hat"] - 0.05) < 1e-7, r
    r = positions_oracle.nonlinear(t, q, s, 0.06, p=p)
    assert abs(r["gamma_hat"] - 0.05) < 1e-7, r


def test_observed_plan_records_are_reproducible_and_sized():
    cases = plan_observed(5, 1, ["linear-px", "oversampled", "long-1e5", "encoder",
                                 "decay-into-noise"])
    a = [generate_observed(c, quick=True) for c in cases]
    b = [generate_observed(c, quick=True) for c in cases]
    for x, y in zip(a, b):
        assert np.array_equal(x["q"], y["q"]) and np.array_equal(x["t"], y["t"])
    assert a[0]["d"] == 2 and a[0]["p"] is None
    assert a[2]["q"].shape == (5000, 1)
    enc = a[3]["q"][:, 0]
    assert np.array_equal(enc, np.round(enc))  # counts
    assert a[4]["p"] is not None
    long = generate_observed(cases[2], quick=False)
    assert long["q"].shape == (100000, 1)


def test_one_coordinate_rk4_gives_the_array_rk4s_bits():
    # rk4 on one trajectory of one coordinate runs on Python floats: the same bits as on arrays,
    # for the pendulum and the Duffing oscillator, a step as a scalar and as a one-column array.
    rng = np.random.default_rng(11)
    for name in ("pendulum", "duffing"):
        s = make_system(name, rng, True)
        for dt in (0.013, np.array([0.021])):
            q = np.array([[rng.uniform(-1.5, 1.5)]])
            p = np.array([[rng.uniform(-1.0, 1.0)]])
            gamma = float(rng.uniform(0.0, 0.3))
            a = rk4(s["grad"], s["theta"], None, gamma, q, p, dt, 500)
            b = rk4_arrays(s["grad"], s["theta"], None, gamma, q, p, dt, 500)
            assert a[0].shape == b[0].shape == (1, 1)
            assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]), (name, a, b)
            assert a[0][0, 0] != q[0, 0]  # it moved


def test_child_cpu_seconds_are_measured():
    rc, out, err, timed_out, cpu = run_child_cpu(
        [sys.executable, "-c", "s = 0\nfor i in range(3000000): s += i\nprint(s)"], 60)
    assert rc == 0 and not timed_out and out.strip() == str(sum(range(3000000)))
    assert cpu > 0.05, cpu
    rc, out, err, timed_out, cpu = run_child_cpu(
        [sys.executable, "-c", "import time; time.sleep(30)"], 0.5)
    assert timed_out


if __name__ == "__main__":
    names = [n for n in sorted(globals()) if n.startswith("test_")]
    for n in names:
        globals()[n]()
        print(f"ok {n}", flush=True)
    print(f"PASS: {len(names)} tests")
