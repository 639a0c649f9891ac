"""Known inputs from Python: identify(q, t, u=...) and CSympNetID().fit(x, t, u=...) run the
driven route of `csympnet fit` (identify_driven) and agree with each other to the bit; bad
inputs are refused with the argument named."""

import numpy as np
import pytest

import csympnet

GAMMA, OMEGA, GAIN = 0.1, 2.0, 1.5


def driven_record(n=1000, h=0.05, noise=0.005, seed=3):
    """q'' + γq' + ω²q = b u(t), u a random-phase multisine; RK4, 20 steps per sample."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * h
    freq = 0.3 + 0.45 * np.arange(8)
    phase = rng.uniform(0.0, 2.0 * np.pi, 8)

    def u(tt):
        return np.sin(freq * tt + phase).sum() / np.sqrt(8.0)

    def field(z, tt):
        return np.array([z[1], -OMEGA**2 * z[0] - GAMMA * z[1] + GAIN * u(tt)])

    z, q, dt = np.array([0.3, 0.0]), np.empty(n), h / 20
    for k in range(n):
        q[k] = z[0]
        for s in range(20):
            ts = t[k] + s * dt
            k1 = field(z, ts)
            k2 = field(z + dt / 2 * k1, ts + dt / 2)
            k3 = field(z + dt / 2 * k2, ts + dt / 2)
            k4 = field(z + dt * k3, ts + dt)
            z = z + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    q += noise * q.std() * rng.normal(size=n)
    return q, t, np.array([u(tt) for tt in t])


def test_identify_with_inputs_recovers_damping_and_gain():
    q, t, u = driven_record()
    r = csympnet.identify(q, t, u=u, observed="positions")
    assert r.identified, r.reasons
    assert r.report["gamma_ci_low"] <= GAMMA <= r.report["gamma_ci_high"]
    inp = r.report["input"]
    assert inp["m"] == 1 and inp["hold"] == "foh"
    assert inp["B_ci_low"][0][0] <= GAIN <= inp["B_ci_high"][0][0]
    est = csympnet.CSympNetID(observed="positions").fit(q, t, u=u[:, None])
    assert est.gamma_ == r.gamma  # one path through the same C++ pipeline
    assert est.report_["input"]["B"] == inp["B"]


def test_bad_inputs_are_refused_by_name():
    q, t, u = driven_record(n=200)
    with pytest.raises(ValueError, match=r"u\[0\]: expected shape \(200,\) or \(200, m\)"):
        csympnet.identify(q, t, u=u[:-1], observed="positions")
    bad = u.copy()
    bad[7] = np.nan
    with pytest.raises(ValueError, match=r"u\[0\]: row 7 is not finite"):
        csympnet.identify(q, t, u=bad, observed="positions")
    with pytest.raises(ValueError, match="u: known inputs go with trajectories"):
        csympnet.CSympNetID(observed="states").fit(np.c_[q, q], t, x_next=np.c_[q, q], u=u)
