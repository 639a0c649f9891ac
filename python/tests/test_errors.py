"""Bad input gives a clear TypeError or ValueError naming the argument, never a crash."""

import numpy as np
import pytest

import csympnet

Z0 = np.zeros((4, 2))
Z1 = np.ones((4, 2))


@pytest.mark.parametrize("args, kwargs, exc, message", [
    ((Z0, Z1[:3], 0.1), {}, ValueError, "z1: has 3 states, expected 4"),
    ((Z0, np.ones((4, 4)), 0.1), {}, ValueError, "z1: states have 4 components, expected 2d = 2"),
    ((np.zeros((4, 3)), np.zeros((4, 3)), 0.1), {}, ValueError, "z0: states have 3 components; expected an even"),
    ((np.zeros(4), Z1, 0.1), {}, ValueError, r"z0: expected a batch \(N, 2d\)"),
    ((np.where(np.eye(4, 2) > 0, np.nan, 0.0), Z1, 0.1), {}, ValueError, r"z0: contains NaN or Inf \(first at index \(0, 0\)\)"),
    ((Z0, Z1, [0.1, 0.1]), {}, ValueError, "h: expected a scalar or an array of 4 steps"),
    ((Z0, Z1, -0.1), {}, ValueError, "h: expected steps > 0"),
    ((Z0, Z1, np.inf), {}, ValueError, "h: contains NaN or Inf"),
    ((Z0.astype(complex), Z1, 0.1), {}, TypeError, "z0: expected real numbers"),
    ((np.array([["a", "b"]] * 4), Z1, 0.1), {}, TypeError, "z0: expected real numbers"),
    (([[1, 2], [3]], Z1, 0.1), {}, ValueError, "z0: cannot be read as an array"),
    ((None, Z1, 0.1), {}, TypeError, "z0: expected an array"),
    ((Z0[:1], Z1[:1], 0.1), {}, ValueError, "at least 2"),
    ((Z0, Z1, 0.1), {"model": "map"}, ValueError, "model: expected one of csympnet, sympnet"),
    ((Z0, Z1, 0.1), {"epochs": 0}, csympnet.Error, "epochs: '0' is out of range; expected a number from 1 to 100000000"),
    ((Z0, Z1, 0.1), {"epochs": 1.5}, TypeError, "epochs: expected an integer"),
    ((Z0, Z1, 0.1), {"core": "la:5"}, ValueError, "core: expected 'la:LAYERS:SUBLAYERS'"),
    ((Z0, Z1, 0.1), {"core": {"type": "xx", "layers": 1}}, csympnet.Error, "unknown core type 'xx'"),
    ((Z0, Z1, 0.1), {"beta_init": 0.0}, csympnet.Error, "beta_init: '0' is zero; expected a nonzero number"),
    ((Z0, Z1, 0.1), {"val_fraction": 1.0}, csympnet.Error, "val_fraction: '1' is out of range; expected a number from 0.01 to 0.99"),
    ((Z0, Z1, 0.1), {"lr_schedule": "step"}, ValueError, "lr_schedule: expected one of cosine, constant"),
    ((Z0, Z1, 0.1), {"progress": 3}, TypeError, "progress: expected a callable"),
    ((Z0, Z1, 0.1), {"validation": (Z0, Z1)}, TypeError, r"validation: expected a \(z0, z1, h\) triple"),
    ((Z0, Z1, 0.1), {"validation": (np.zeros((2, 4)),) * 2 + (0.1,)}, ValueError, "validation z0: states have 4 components, expected 2"),
    ((Z0, Z1, 0.1), {"epoch": 10}, TypeError, "unexpected keyword argument 'epoch'"),
])
def test_fit_rejects(args, kwargs, exc, message):
    with pytest.raises(exc, match=message):
        csympnet.fit(*args, **kwargs)


def test_model_methods_reject(s1_model):
    m = s1_model
    cases = [
        (lambda: m.predict([1.0, 2.0, 3.0], 0.1), ValueError, "z: states have 3 components, expected 2d = 2"),
        (lambda: m.predict(np.zeros((2, 2, 2)), 0.1), ValueError, r"z: expected a state \(2d,\) or a batch"),
        (lambda: m.predict([np.nan, 0.0], 0.1), ValueError, "z: contains NaN"),
        (lambda: m.predict([0.0, 0.0], 0.0), ValueError, "h: expected steps > 0"),
        (lambda: m.predict([0.0, 0.0], "0.1"), TypeError, "h: expected real numbers"),
        (lambda: m.predict(np.zeros((3, 2)), [0.1, 0.1]), ValueError, "h: expected a scalar or an array of 3"),
        (lambda: m.rollout([0.0, 0.0], 0.1), ValueError, "hs: a single step needs steps=n"),
        (lambda: m.rollout([0.0, 0.0], [[0.1]]), ValueError, "hs: expected a 1-D array"),
        (lambda: m.rollout([0.0, 0.0], 0.1, steps=-1), ValueError, "steps: expected an integer >= 0"),
        (lambda: m.rollout(np.zeros((0, 2)), [0.1]), ValueError, "z0: expected a state"),
        (lambda: m.jacobian([0.0, 0.0, 0.0, 0.0], 0.1), ValueError, "z: states have 4 components"),
        (lambda: m.structure([0.0, 0.0], 0.1, gamma_true=-1.0), ValueError, "gamma_true: expected a number >= 0"),
        (lambda: m.diagnostics(preset="s9"), ValueError, "preset: expected one of s1"),
        (lambda: m.diagnostics(preset="s2"), ValueError, "system: has d = 10, but the model has d = 1"),
        (lambda: m.diagnostics({"kind": "oscillator"}), ValueError, "expected at least the fields 'kind' and 'd'"),
        (lambda: m.diagnostics({"kind": "spring", "d": 1}), csympnet.Error, "kind"),
        (lambda: m.diagnostics(tests=[(np.arange(3.0), np.zeros((2, 2)))]), ValueError, r"tests\[0\] t: has 3 entries, expected 2"),
        (lambda: m.diagnostics(tests=[([0.0, 0.0], np.zeros((2, 2)))]), ValueError, "strictly increasing"),
        (lambda: m.diagnostics(h_test=0), ValueError, "h_test: expected a number > 0"),
    ]
    for call, exc, message in cases:
        with pytest.raises(exc, match=message):
            call()


def test_data_functions_reject():
    cases = [
        (lambda: csympnet.generate("s7"), ValueError, "preset: expected one of"),
        (lambda: csympnet.generate("s1", "training"), ValueError, "split: expected one of train, val, test"),
        (lambda: csympnet.generate("s1", n=0), ValueError, "n: expected an integer >= 1"),
        (lambda: csympnet.generate("s1", seed=2**64), ValueError, "seed: expected an integer <= "),
        (lambda: csympnet.generate("s1", sigma=-1), ValueError, "sigma: expected a number >= 0"),
        (lambda: csympnet.generate("s1", h=(0.2, 0.1)), ValueError, "h: expected"),
        (lambda: csympnet.generate("s1", system={"gama": 0.1}), csympnet.Error, "gama"),
        (lambda: csympnet.generate("s1", system={"gamma": -1.0}), csympnet.Error, "gamma"),
        (lambda: csympnet.System(kind="cubic", d=0), csympnet.Error, "d"),
        (lambda: csympnet.System().flow([0.0, 0.0], 0.1, reference="euler"), ValueError, "reference: expected one of"),
        (lambda: csympnet.System(kind="cubic").flow([0.0, 0.0], 0.1, reference="expm"), csympnet.Error, "linear"),
        (lambda: csympnet.fit_trajectories(np.zeros((3, 2)), [0.0, 1.0, 2.0], traj=[0, 1, 0]), ValueError, "not contiguous"),
        (lambda: csympnet.fit_trajectories(np.zeros((3, 2)), [0.0, 1.0, 0.5]), ValueError, "strictly increasing"),
        (lambda: csympnet.fit_trajectories(np.zeros((1, 2)), [0.0]), ValueError, "give no pairs"),
        (lambda: csympnet.run("s1", "nope"), ValueError, "model: expected one of csympnet"),
        (lambda: csympnet.load(123), TypeError, ""),
        (lambda: csympnet.Model(object()), TypeError, "made by csympnet.fit"),
    ]
    for call, exc, message in cases:
        with pytest.raises(exc, match=message):
            call()


def test_an_unconstructed_core_model_raises_instead_of_crashing():
    # Model.__new__ without a constructor leaves no C++ object behind the Python one; every
    # attribute and method must raise, and the interpreter must survive (a crash here kills
    # the whole test run).
    core = csympnet._core
    m = core.Model.__new__(core.Model)
    for name in ["type", "dim", "n_params", "is_map", "gamma", "gamma_interval", "params",
                 "hyperparams_json", "meta_json", "training_json"]:
        with pytest.raises(RuntimeError, match="never constructed"):
            getattr(m, name)
    calls = [("predict", ([[0.0, 0.0]], [0.1], True)), ("rollout", ([0.0, 0.0], [0.1])),
             ("jacobian", ([0.0, 0.0], 0.1)), ("structure", ([0.0, 0.0], 0.1, 0.1)),
             ("save", ("unused.json", "{}")), ("to_json", ("{}",)),
             ("evaluate", ("{}", [], 0.1))]
    for name, args in calls:
        with pytest.raises(RuntimeError, match="never constructed"):
            getattr(m, name)(*args)
    # An unbound method called on something that is not a Model.
    with pytest.raises(TypeError, match="expected a csympnet._core.Model"):
        core.Model.type.fget(42)
    del m
