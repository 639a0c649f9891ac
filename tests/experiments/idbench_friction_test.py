#!/usr/bin/python3
"""Tests of the friction plan of the identification benchmark (experiments/idbench/friction*.py
and its peers): the simulators against exact properties (a Coulomb half cycle loses exactly
2 mu / omega^2 and sticks in the dead band; the pendulum's reversals and sticking agree with the
exact oscillator at small amplitude; drag converges in its substeps), the envelope fit on clean
records and the oracle on noisy ones (errors the size of its standard errors, residuals at the
noise), csympnet's dissipation terms read from its report, and the
plan from the command line, deterministic given the seed. Runs under pytest, or as a plain
script (ctest runs it so, needing only /usr/bin/python3 with NumPy and SciPy)."""
import json
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "..", "experiments"))

from idbench import friction  # noqa: E402
from idbench import friction_chain  # noqa: E402
from idbench.friction_plan import csympnet_dissipation, score_rate  # noqa: E402
from idbench.peers.chain_oracle import chain_oracle_arguments  # noqa: E402
from idbench.peers.friction_oracle import friction_oracle  # noqa: E402
from idbench.peers.friction_textbook import envelope_fit  # noqa: E402


def test_a_coulomb_half_cycle_loses_two_mu_over_omega_squared_and_sticks_in_the_dead_band():
    omega, mu = 1.7, 0.05
    q, v = 1.3, 0.0
    amps = [q]
    for _ in range(200):  # half cycles of pi / omega
        q, v = friction.coulomb_advance(omega, 0.0, mu, q, v, math.pi / omega)
        amps.append(abs(q))
        if v == 0.0 and omega * omega * abs(q) <= mu and abs(abs(q) - amps[-2]) < 1e-15:
            break
    drops = -np.diff(amps)
    full = np.array(amps[1:]) * omega * omega > mu  # half cycles that end outside the dead band
    assert full.sum() > 10
    assert np.allclose(drops[full], 2 * mu / omega ** 2, rtol=0, atol=1e-12), drops[full]
    assert omega * omega * amps[-1] <= mu  # at rest in the dead band, for good
    assert friction.coulomb_advance(omega, 0.0, mu, q, 0.0, 10.0) == (q, 0.0)


def test_the_pendulum_reversals_and_sticking_agree_with_the_exact_oscillator_at_small_amplitude():
    # sin q = q (1 - q^2/6 + ...): at amplitude 1e-3 the pendulum is the oscillator to ~2e-7
    omega, gamma, mu, h = 2.0, 0.05, 2e-4, 0.05
    a = friction.simulate("pendulum-coulomb", omega, gamma, mu, 1e-3, 0.0, h, 400)
    b = friction.simulate("coulomb", omega, gamma, mu, 1e-3, 0.0, h, 400)
    assert np.max(np.abs(a - b)) < 5e-9, np.max(np.abs(a - b))
    assert a[-1, 1] == 0.0 and b[-1, 1] == 0.0  # both stuck by the end
    assert np.all(np.abs(a[:, 0]) <= 1e-3 + 1e-15)


def test_drag_converges_in_its_substeps_and_loses_energy():
    z = friction.simulate("drag", 2.2, 0.04, 0.3, 1.5, 0.0, 0.1, 200)
    fine = friction.simulate("drag", 2.2, 0.04, 0.3, 1.5, 0.0, 0.1, 200, substeps=4000)
    assert np.max(np.abs(z - fine)) < 1e-11
    energy = 0.5 * z[:, 1] ** 2 + 0.5 * 2.2 ** 2 * z[:, 0] ** 2
    assert np.all(np.diff(energy) < 0)


def _record(kind, rate, noise, seed=5, span=60.0, positions_only=False):
    rng = np.random.default_rng(seed)
    omega, gamma = 2.0, 0.08
    h = 2 * math.pi / omega / 30
    points = int(span / h)
    zs = [friction.simulate(kind, omega, gamma, rate, q0, 0.0, h, points) for q0 in (1.6, -1.2)]
    zs = [z + noise * z.std(axis=0) * rng.standard_normal(z.shape) for z in zs]
    rec = {"t": np.concatenate([np.arange(points) * h] * 2),
           "traj": np.repeat([0, 1], points), "q": np.concatenate([z[:, 0] for z in zs]),
           "p": None if positions_only else np.concatenate([z[:, 1] for z in zs])}
    truth = {"kind": kind, "omega": omega, "gamma": gamma, "rate": rate, "h": h,
             "points": points, "scale": 1.0, "offset": 0.0, "rate_in_units": rate}
    return rec, truth


def test_the_envelope_fit_recovers_viscous_damping_and_dry_friction_on_clean_records():
    rec, _ = _record("viscous", 0.0, 0.0)
    r = envelope_fit(rec, "viscous")
    assert abs(r["gamma_hat"] - 0.08) < 0.01 * 0.08, r
    rec, _ = _record("coulomb", 0.06, 0.0)
    r = envelope_fit(rec, "coulomb")
    assert abs(r["gamma_hat"] - 0.08) < 0.03 * 0.08, r
    assert abs(r["rate"]["value"] - 0.06) < 0.03 * 0.06, r
    # an offset record: the rest position is found, not assumed to be 0
    rec["q"] = rec["q"] + 123.4
    r2 = envelope_fit(rec, "coulomb")
    assert abs(r2["gamma_hat"] - r["gamma_hat"]) < 1e-3 * r["gamma_hat"], (r, r2)


class _NoJitter:
    def standard_normal(self, n):
        return np.full(n, 1.0)  # a start 22% off in gamma and the rate


def _z_scores(r, rate):
    se = (r["ci_high"] - r["ci_low"]) / (2 * 1.96)
    se_rate = (r["rate"]["high"] - r["rate"]["low"]) / (2 * 1.96)
    return (r["gamma_hat"] - 0.08) / se, (r["rate"]["value"] - rate) / se_rate


def test_the_oracle_errors_are_the_size_of_its_standard_errors_on_noisy_records():
    """Dry friction from positions alone, eight noisy records: the errors over the standard
    errors have a median |z| near a Gaussian's 0.67 (below 1.2) and none beyond 6 (a stick
    makes the tails heavier than Gaussian); the residuals are the noise. Drag (a smooth form),
    one record: within three standard errors."""
    zs = []
    for seed in range(1, 9):
        rec, truth = _record("coulomb", 0.06, 3e-3, seed=seed, span=30.0, positions_only=True)
        r = friction_oracle(rec, truth, _NoJitter())
        assert r["extra"]["residual_sd"] < 1.2 * 3e-3, (seed, r)
        zs += list(_z_scores(r, 0.06))
    assert np.median(np.abs(zs)) < 1.2 and np.max(np.abs(zs)) < 6, np.round(zs, 2)
    rec, truth = _record("drag", 0.2, 3e-3, span=30.0)
    r = friction_oracle(rec, truth, _NoJitter())
    assert max(map(abs, _z_scores(r, 0.2))) < 3 and r["extra"]["residual_sd"] < 1.2 * 3e-3, r


def test_csympnet_dissipation_terms_are_read_beyond_the_viscous_one():
    tmp = tempfile.mkdtemp()
    rep = {"dissipation": {"terms": [
        {"kind": "viscous", "dof": None, "value": 0.1, "low": 0.09, "high": 0.11},
        {"kind": "coulomb", "dof": 0, "value": 0.3, "low": 0.28, "high": 0.32, "unit": "x"}]}}
    with open(os.path.join(tmp, "report.json"), "w") as f:
        json.dump(rep, f)
    assert csympnet_dissipation(tmp) == [{"kind": "coulomb", "dof": 0, "value": 0.3,
                                          "low": 0.28, "high": 0.32}]
    assert csympnet_dissipation(os.path.join(tmp, "absent")) is None


def test_the_two_mass_chain_decoupled_is_the_one_dof_closed_form_on_each_mass():
    h, g = 2 * math.pi / 2.9 / 30, 0.08
    k = np.diag([2.1 ** 2, 2.9 ** 2])
    z = friction_chain.simulate_chain(k, g, [0.2, 0.1], [1.4, -1.1], [0.3, 0.5], h, 600)
    a = friction.simulate("coulomb", 2.1, g, 0.2, 1.4, 0.3, h, 600)
    b = friction.simulate("coulomb", 2.9, g, 0.1, -1.1, 0.5, h, 600)
    assert np.max(np.abs(z[:, [0, 2]] - a)) < 1e-12, np.max(np.abs(z[:, [0, 2]] - a))
    assert np.max(np.abs(z[:, [1, 3]] - b)) < 1e-12, np.max(np.abs(z[:, [1, 3]] - b))
    assert a[-1, 1] == 0.0 and z[-1, 2] == 0.0  # both at rest for good by the end


def test_the_coupled_chain_loses_energy_sticks_in_its_dead_band_and_converges():
    # coupled masses: the energy 1/2 v.v + 1/2 q.K q never rises; at a sample where a mass is
    # at rest its spring force is within its friction (it sticks); the record ends at rest with
    # both in their dead bands; and the event location is exact: halving the step agrees
    rng = np.random.default_rng(3)
    for _ in range(3):
        t = friction_chain.chain_truth(rng)
        k, mu = np.array(t["k"]), np.array(t["rate"])
        h = 2 * math.pi / max(t["omega"]) / 30
        z = friction_chain.simulate_chain(k, t["gamma"], mu, [1.5, -0.9], [0.2, -0.4], h, 1500)
        q, v = z[:, :2], z[:, 2:]
        energy = 0.5 * np.sum(v * v, axis=1) + 0.5 * np.einsum("ni,ij,nj->n", q, k, q)
        assert np.all(np.diff(energy) <= 1e-12 * energy[0]), np.max(np.diff(energy))
        assert np.all(v[-1] == 0.0) and np.all(np.abs(k @ q[-1]) <= mu * (1 + 1e-12))
        fine = friction_chain.simulate_chain(k, t["gamma"], mu, [1.5, -0.9], [0.2, -0.4],
                                             h / 2, 2999)[::2]
        assert np.max(np.abs(fine - z)) < 1e-9, np.max(np.abs(fine - z))


def test_rates_of_two_masses_are_scored_by_their_worst():
    truth = {"kind": "coulomb", "rate_in_units": [0.1, 0.2]}
    res = {"status": "ok", "rate": {"kind": "coulomb", "dof": 1, "value": 0.105},
           "rates": [{"kind": "coulomb", "dof": 1, "value": 0.105, "low": 0.1, "high": 0.11},
                     {"kind": "coulomb", "dof": 2, "value": 0.22, "low": 0.21, "high": 0.23}]}
    r = score_rate(res, truth)
    assert abs(r["rate_rel_err"] - 0.1) < 1e-12 and r["rate_covers"] is False
    assert r["rate_dofs_covered"] == 1


def test_the_chain_oracle_gives_the_true_form_in_place_of_the_callers_core():
    args = chain_oracle_arguments(["--core", "la:4:8", "--dissipation=auto", "--seed", "3",
                                   "--dissipation", "viscous"])
    assert args[:2] == ["--seed", "3"] and args[2] == "--core" and len(args) == 4
    core = json.loads(args[3])
    assert core["type"] == "library"
    # a quadratic potential in two coordinates (every quadratic form, and the linear terms
    # because the library's terms are centred on the data's mean) and dry friction on each mass
    assert sorted(core["terms"]) == sorted(["q1", "q2", "q1^2", "q2^2", "(q1-q2)^2"])
    assert core["dissipation"] == ["coulomb(p1)", "coulomb(p2)"]


def test_a_violation_answer_that_names_its_dissipation_is_judged_on_the_viscous_part():
    from idbench.common import violation_reference
    from idbench.runner import score_violation
    v = {"family": "coulomb", "gamma_reference": 0.2, "gamma_reference_range": [0.2, 0.2],
         "gamma_viscous": 0.1}
    assert violation_reference(v, ["coulomb"]) == (0.1, (0.1, 0.1))
    assert violation_reference(v, []) == (0.2, (0.2, 0.2))
    assert violation_reference(v, ["drag"]) == (0.2, (0.2, 0.2))  # not the family's own term
    named = score_violation({"status": "ok", "gamma_hat": 0.1, "ci_low": 0.09, "ci_high": 0.11,
                             "dissipation_kinds": ["coulomb"]}, v)
    assert named["judged_on_viscous"] and not named["confident_wrong"] and named["covers"]
    folded = score_violation({"status": "ok", "gamma_hat": 0.1, "ci_low": 0.09, "ci_high": 0.11,
                              "dissipation_kinds": []}, v)
    assert not folded["judged_on_viscous"] and folded["confident_wrong"]
    modes = {"family": "nonuniform", "gamma_reference": 0.2, "gamma_reference_range": [0.1, 0.3]}
    assert violation_reference(modes, ["coulomb"]) == (0.2, (0.1, 0.3))


def test_friction_plan_runs_from_the_command_line_and_is_deterministic():
    script = os.path.join(HERE, "..", "..", "experiments", "identification_benchmark.py")
    outs = []
    for k in range(2):
        out = os.path.join(tempfile.mkdtemp(), "out")
        r = subprocess.run([sys.executable, script, "--friction-plan", "--quick", "--cases", "3",
                            "--friction-strata", "coulomb-positions,drag,encoder-pendulum",
                            "--only-peers", "--out", out],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr[-2000:]
        with open(os.path.join(out, "results.json")) as f:
            outs.append(json.load(f))
    strip = lambda c: {m: {k: v for k, v in r.items() if "seconds" not in k}  # noqa: E731
                       for m, r in c["methods"].items()}
    assert [strip(c) for c in outs[0]["cases"]] == [strip(c) for c in outs[1]["cases"]]
    for c in outs[0]["cases"]:
        assert c["methods"]["csympnet"]["status"] == "skipped"
        o = c["methods"]["oracle"]
        assert o["status"] == "ok" and o["rel_err"] < 0.05 and o["rate_rel_err"] < 0.1, (c["id"], o)
    with open(os.path.join(out, "cases", "f002-encoder-pendulum", "record.csv")) as f:
        header, first = f.readline().strip(), f.readline().strip().split(",")
    assert header == "traj,t,q1" and float(first[2]).is_integer()  # encoder counts


if __name__ == "__main__":
    from script_tests import run
    run(globals())
