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


@pytest.fixture(scope="module")
def driven_model():
    q, t, u = driven_record()
    r = csympnet.identify(q, t, u=u, observed="positions")
    assert r.identified, r.reasons
    return r.model, t[1] - t[0]


def test_a_driven_model_simulates_a_held_out_record_from_its_warm_up(driven_model):
    model, _ = driven_model
    q, t, u = driven_record(n=300, seed=4)
    assert model.n_inputs == 1
    state, rms = model.state_from_positions(q[:20], t[:20], u=u[:20])
    assert rms < 0.02 * q.std()
    run = model.simulate(state, t[19:], u[19:])
    assert run.shape == (281, 2) and np.array_equal(run[0], state)
    err = run[1:, 0] - q[20:]
    assert np.sqrt(np.mean(err**2)) < 0.03 * q.std()
    # the inputs are what drive it: the same start without them drifts off the record
    still = model.simulate(state, t[19:], np.zeros(281))
    assert np.sqrt(np.mean((still[1:, 0] - q[20:]) ** 2)) > 0.3 * q.std()


def test_the_linear_response_is_its_own_simulation_and_the_oscillators(driven_model):
    model, h = driven_model
    w = np.array([0.5, 1.2, 1.9, 2.0, 2.1, 3.0, 5.0])
    lin = model.frequency_response(w, h)
    g = lin["response"][:, 0, 0]
    # two paths through the map: its Jacobians at the equilibrium, and a small sinusoid run
    # until it repeats
    sim = model.frequency_response(w, h, amplitude=1e-3)
    assert sim["settled"].all()
    assert np.max(np.abs(sim["response"][:, 0] - g) / np.abs(g)) < 1e-4
    # the oscillator the record came from, its input held on the straight line between
    # samples as the model holds it (the first-order hold passes a sinusoid's fundamental
    # times sinc²(ωh/2))
    hold = np.sinc(w * h / (2 * np.pi)) ** 2
    truth = GAIN / (OMEGA**2 - w**2 + 1j * GAMMA * w) * hold
    assert np.max(np.abs(g - truth) / np.abs(truth)) < 0.02
    (wn, zeta), = lin["modes"]
    assert abs(wn - OMEGA) < 0.01 * OMEGA and abs(zeta - GAMMA / (2 * OMEGA)) < 0.1 * zeta
    # a nonlinear response at a large amplitude is still this linear map's
    big = model.frequency_response(w[:3], h, amplitude=10.0)
    assert np.max(np.abs(big["response"][:, 0] - g[:3]) / np.abs(g[:3])) < 1e-3


def test_the_frequency_response_refuses_what_it_cannot_do(driven_model, s1_model):
    model, h = driven_model
    with pytest.raises(ValueError, match="Nyquist"):
        model.frequency_response([1.0, np.pi / h], h)
    with pytest.raises(ValueError, match="positive finite"):
        model.frequency_response([0.0, 1.0], h)
    with pytest.raises(ValueError, match="no inputs"):
        s1_model.frequency_response([1.0], 0.1)
    with pytest.raises(ValueError, match="no inputs"):
        s1_model.simulate(np.zeros(2), [0.0, 0.1], [[0.0], [0.0]])
    with pytest.raises(Exception, match=r"u must be \(3, 1\)"):
        model.simulate(np.zeros(2), [0.0, 0.1, 0.2], np.zeros((2, 1)))
    with pytest.raises(Exception, match="give the window's inputs"):
        model.state_from_positions(np.zeros(5), np.arange(5) * h)


@pytest.mark.long
def test_a_named_neural_core_takes_the_inputs_and_simulates():
    """core="g:6:8": CSympNet-ID with a G core and the input's half-kicks, started from the
    library fit and fitted on the positions; the model reads the input, its free run follows a
    held-out record, and its linearisation has the oscillator's mode."""
    q, t, u = driven_record(n=2000, h=0.1, seed=5)
    r = csympnet.identify(q, t, u=u, observed="positions", core="g:6:8")
    neural = r.report["choices"]["driven"]["neural"]
    assert neural["chosen"] == "g:6:8" and neural["named"]
    assert r.model.n_inputs == 1
    assert r.report["hamiltonian"] is None and r.report["input"]["B"] is None
    assert len(r.report["input"]["B_momentum"]) == 1
    assert r.identified, r.reasons
    assert r.report["gamma_ci_low"] <= GAMMA <= r.report["gamma_ci_high"]
    q2, t2, u2 = driven_record(n=200, h=0.1, seed=6)
    state, rms = r.model.state_from_positions(q2[:20], t2[:20], u=u2[:20])
    run = r.model.simulate(state, t2[19:], u2[19:])
    assert np.sqrt(np.mean((run[:, 0] - q2[19:]) ** 2)) < 0.1 * q2.std()
    fr = r.model.frequency_response(np.array([1.0, 2.0, 3.0]), h=0.1)
    assert len(fr["modes"]) == 1
    assert abs(fr["modes"][0][0] - OMEGA) < 0.05 * OMEGA
