"""The user's records, read once (csympnet/_records.py): every form the entries take becomes the
same trajectories, positions stay d columns on their way to the library, and a refusal names
the argument and what was expected."""

import warnings

import numpy as np
import pytest

import csympnet
from csympnet import _records

T = np.arange(12) * 0.1
Q = np.cos(T)
Z = np.stack([Q, -np.sin(T)], axis=1)


def arrays_of(records):
    return [(tr.t, tr.z) for tr in records.trajectories]


def is_library_ready(a):
    return a.dtype == np.float64 and a.flags.c_contiguous


# --- each input kind ---------------------------------------------------------------------

def test_one_trajectory_of_states():
    r = _records.read(Z, T, None, observed="states")
    (t, z), = arrays_of(r)
    assert np.array_equal(t, T) and np.array_equal(z, Z)
    assert is_library_ready(t) and is_library_ready(z)
    assert r.observed == "states" and not r.positions_only and not r.pairs
    assert r.inputs is None and r.time_unit is None and r.unit_source == "time_unit"
    assert np.array_equal(r.steps(), np.diff(T))


@pytest.mark.parametrize("q, d", [(Q, 1), (Q[:, None], 1), (np.c_[Q, 2 * Q, 3 * Q], 3)])
def test_positions_travel_as_positions(q, d):
    """d columns, never padded with zero momenta: an odd d stays odd."""
    r = _records.read(q, T, None, observed="positions")
    (t, z), = arrays_of(r)
    assert r.positions_only and z.shape == (len(T), d)
    assert np.array_equal(z, np.reshape(q, (len(T), d))) and is_library_ready(z)


def test_lists_and_stacks_and_labels_give_the_same_trajectories():
    z2 = 2.0 * Z
    listed = _records.read([Z, z2], [T, T + 5.0], None, observed="states")
    stacked = _records.read(np.stack([Z, z2]), np.stack([T, T + 5.0]), None, observed="states")
    labelled = _records.read(np.r_[Z, z2], np.r_[T, T + 5.0], np.r_[[0] * 12, [1] * 12],
                             observed="states")
    for other in (stacked, labelled):
        for (ta, za), (tb, zb) in zip(arrays_of(listed), arrays_of(other)):
            assert np.array_equal(ta, tb) and np.array_equal(za, zb)
    shared = _records.read(np.stack([Z, z2]), T, None, observed="states")  # t (M,) for all
    assert [np.array_equal(t, T) for t, _ in arrays_of(shared)] == [True, True]


def test_the_other_entries_read_the_same_forms():
    """fit_trajectories and Model.score take identify's forms through the same function."""
    direct = _records.trajectories([Z, Z[:5]], [T, T[:5]])
    assert [tr.z.shape for tr in direct] == [(12, 2), (5, 2)]
    named = _records.trajectories(Q, T, observed="positions", name="data", dim=1)
    assert named[0].z.shape == (12, 1)
    with pytest.raises(ValueError, match=r"data\[0\] z: positions have 1 columns, expected d = 2"):
        _records.trajectories(Q, T, observed="positions", name="data", dim=2)
    with pytest.raises(ValueError, match=r"data\[0\] z: states have 2 components, expected 2d = 4"):
        _records.trajectories(Z, T, name="data", dim=4)


def test_pairs_are_two_sample_trajectories():
    h = np.full(11, 0.1)
    r = _records.read(None, None, None, pairs_given=(Z[:-1], Z[1:], h))
    assert r.pairs and len(r.trajectories) == 11
    t0, z0 = arrays_of(r)[0]
    assert np.array_equal(t0, [0.0, 0.1]) and np.array_equal(z0, Z[:2])
    assert np.array_equal(r.steps(), h)  # 0 + h - 0 is h exactly
    p = _records.pairs("validation ", Z[:-1], Z[1:], 0.1)
    assert isinstance(p, csympnet.Pairs) and np.array_equal(p.h, h)


def test_known_inputs_are_one_array_per_trajectory():
    u = np.sin(T)
    r = _records.read(Q, T, None, observed="positions", u=u)
    assert [a.shape for a in r.inputs] == [(12, 1)]
    r = _records.read([Q, Q], [T, T], None, observed="positions", u=[u, np.c_[u, u]])
    assert [a.shape for a in r.inputs] == [(12, 1), (12, 2)]
    with pytest.raises(ValueError, match=r"u\[0\]: expected shape \(12,\) or \(12, m\)"):
        _records.read(Q, T, None, observed="positions", u=u[:-1])
    with pytest.raises(ValueError, match=r"u: expected one array of inputs per trajectory \(2\)"):
        _records.read([Q, Q], [T, T], None, observed="positions", u=u)
    with pytest.raises(ValueError, match="u: known inputs go with trajectories"):
        _records.read(np.r_[Q, Q], np.r_[T, T], [0] * 12 + [1] * 12, observed="positions", u=u)


def test_the_estimators_times_a_step_or_none():
    with pytest.warns(csympnet.NoTimesWarning, match="per sample"):
        none = _records.read_estimator(Z, None, observed="states")
    assert np.array_equal(none.trajectories[0].t, np.arange(12.0))
    step = _records.read_estimator([Z, Z], 0.1, observed="states")
    assert all(np.array_equal(tr.t, 0.1 * np.arange(12)) for tr in step.trajectories)
    default = _records.read_estimator(Q, None, observed="positions", t_default=0.5)
    assert default.trajectories[0].z.shape == (12, 1)
    pairs = _records.read_estimator(Z[:-1], 0.1, x_next=Z[1:], observed="states")
    assert pairs.pairs and np.array_equal(pairs.steps(), np.full(11, 0.1))
    score = _records.read_estimator_score(Z, None, step=0.1, dim=2)
    assert np.array_equal(score[0].t, 0.1 * np.arange(12))
    with pytest.raises(ValueError, match="x_next: pairs need whole states"):
        _records.read_estimator(Q, 0.1, x_next=Q, observed="positions")
    with pytest.raises(ValueError, match=r"x: score takes states \(q, p\), 2 columns"):
        _records.read_estimator_score(Q[:, None], T, step=0.1, dim=2, fitted_on_positions=True)


def test_a_dataframe_is_read_by_its_column_names():
    pd = pytest.importorskip("pandas")
    states = _records.read(pd.DataFrame({"t": T, "p1": Z[:, 1], "q1": Z[:, 0]}), None, None)
    assert states.observed == "states" and np.array_equal(states.trajectories[0].z, Z)
    cart = pd.DataFrame({"t_ms": 1e3 * T, "traj": [0] * 6 + [1] * 6, "x_px": Q})
    with warnings.catch_warnings():
        warnings.simplefilter("error", csympnet.LayoutWarning)  # the names said positions
        r = _records.read(cart, None, None)
    assert r.positions_only and [tr.z.shape for tr in r.trajectories] == [(6, 1), (6, 1)]
    assert r.time_unit == "ms" and r.unit_source == "column 't_ms'"
    series = _records.read(pd.Series(Q, index=pd.Index(T, name="t_s")), None, None)
    assert series.positions_only and np.array_equal(series.trajectories[0].t, T)
    with pytest.raises(ValueError, match="x_next: pairs are arrays"):
        _records.read_estimator(cart, None, x_next=Z)


def test_an_array_without_observed_is_read_as_states_with_a_warning():
    with pytest.warns(csympnet.LayoutWarning, match=r"\(q1, p1\), d = 1"):
        r = _records.read(Z, T, None)
    assert r.observed == "states"
    with warnings.catch_warnings():
        warnings.simplefilter("error", csympnet.LayoutWarning)
        _records.read(None, None, None, pairs_given=(Z[:-1], Z[1:], np.diff(T)))


# --- refusals name the argument ----------------------------------------------------------

@pytest.mark.parametrize("call, exc, message", [
    (lambda: _records.read(Z, None, None, observed="states"), ValueError,
     "t: the sample times are needed"),
    (lambda: _records.read(Z, T, None, observed="momenta"), ValueError,
     "observed: expected one of states, positions"),
    (lambda: _records.read(Z, T, None, time_unit="fortnight"), ValueError, "time_unit: expected"),
    (lambda: _records.read(Z.astype(complex), T, None, observed="states"), TypeError,
     "z: expected real numbers"),
    (lambda: _records.read(np.where(Z > 0.99, np.nan, Z), T, None, observed="states"),
     ValueError, r"z: contains NaN or Inf \(first at index \(0, 0\)\); expected finite"),
    (lambda: _records.read(Z, T[::-1], None, observed="states"), ValueError,
     r"trajectories\[0\] t: expected strictly increasing times"),
    (lambda: _records.read(Z, T[:-1], None, observed="states"), ValueError,
     "t: has 11 entries, expected 12"),
    (lambda: _records.read(np.zeros((2, 3, 4, 1)), T, None, observed="positions"), ValueError,
     r"z: expected positions \(M, d\), or \(M,\) for d = 1"),
    (lambda: _records.read(np.r_[Z, Z], np.r_[T, T + 2], [0] * 6 + [1] * 12 + [0] * 6,
                           observed="states"), ValueError, "traj: the rows of trajectory 0 are "
     "not contiguous"),
    (lambda: _records.read([Q, np.c_[Q, Q]], [T, T], None, observed="positions"), ValueError,
     r"z\[1\]: 2 position columns \(d = 2\), but z\[0\] has 1 \(d = 1\)"),
    (lambda: _records.read(1e200 * Z, T, None, observed="states"), ValueError,
     r"trajectory 0 z: .* too large to train on"),
    (lambda: _records.read(Q, T, None, pairs_given=(Z, Z, T)), ValueError,
     "pairs: give either pairs=.z0, z1, h. or trajectories"),
    (lambda: _records.read(None, None, None, pairs_given=(Z, Z[:3], T)), ValueError,
     r"pairs z1: expected shape \(12, 2\)"),
    (lambda: _records.read(None, None, None, pairs_given=(Z, Z, T), observed="positions"),
     ValueError, 'observed: "positions" needs trajectories'),
    (lambda: _records.read_estimator([], 0.1, observed="states"), ValueError,
     "x: expected at least one trajectory"),
    (lambda: _records.read_estimator([Z, Z], [T], observed="states"), ValueError,
     "t: 1 time arrays for 2 trajectories"),
    (lambda: _records.read_estimator(Z, -0.1, observed="states"), ValueError,
     "t: expected a number > 0"),
    (lambda: _records.read_estimator(Z, 0.1, x_next=Z[:3], observed="states"), ValueError,
     r"x_next: expected shape \(12, 2\), got \(3, 2\)"),
    (lambda: _records.read_estimator([Z, Z], 0.1, observed="states", u=T), ValueError,
     "u: expected a list of 2 input arrays, one per trajectory of x"),
    (lambda: _records.read(Q, T, None, observed="positions", u=np.array(["on"] * 12)),
     TypeError, r"u\[0\]: expected real numbers"),
    (lambda: _records.pairs("", Z, Z[:3], 0.1), ValueError, "z1: has 3 states, expected 12"),
    (lambda: _records.trajectory_list([(T, Z, T)], "tests"), TypeError,
     r"tests\[0\]: expected a \(t, z\) pair"),
    (lambda: _records.trajectory_list([], "tests"), TypeError,
     "tests: expected a non-empty list"),
])
def test_refusals_name_the_argument_and_what_was_expected(call, exc, message):
    with pytest.raises(exc, match=message):
        call()


def test_the_library_takes_positions_of_any_d():
    """The binding's positions entry reads (M, d) as it is: three position columns (an odd
    count, which no state has) reach identify_positions, whose own check speaks."""
    q = np.c_[np.cos(T), np.sin(T), np.ones_like(T)]
    with pytest.raises(csympnet.Error, match="q3 does not vary"):
        csympnet.identify(q, T, observed="positions", epochs=1, lm_iterations=1)
