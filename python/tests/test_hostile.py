"""The Python part of the hostile-input suite (docs/hardening.md, "The hostile-input suite").

Every public entry point gets values a careless or hostile caller could pass: wrong types,
shapes and sizes, NaN and infinities, subnormal, huge and negative numbers, empty and ragged
arrays, non-contiguous and read-only views, objects that raise when read, bad files. For each:
no crash (the interpreter survives: a crash would end the run), no hang (tiny budgets), and no
silent wrong result: either a ValueError/TypeError/OSError (csympnet.Error is a ValueError)
whose message names the argument and says what was expected, or an answer that is finite and
unchanged by the caller's view of the data.
"""

import json
import math
import os
import signal
import stat
import threading
import time

import numpy as np
import pytest

import csympnet

RNG = np.random.default_rng(5)
Z0 = RNG.uniform(-1, 1, (12, 2))
Z1 = Z0 * 0.99
H = 0.1
REFUSED = (ValueError, TypeError, OSError)


class Exploding:
    """An array-like that raises when NumPy reads it."""

    def __array__(self, *args, **kwargs):
        raise RuntimeError("boom")


def _bad_arrays(shape):
    """Values that are not an array of real numbers of `shape`."""
    n, m = shape
    good = RNG.uniform(-1, 1, shape)
    cases = {
        "none": None, "string": "abc", "dict": {"a": 1}, "set": {1, 2},
        "ragged": [[1.0, 2.0], [3.0]], "complex": good.astype(complex),
        "strings": np.full(shape, "x"), "objects": np.full(shape, object()),
        "bools": np.ones(shape, bool), "empty": np.zeros((0, m)),
        "scalar": 1.0, "three_d": np.zeros((2, n, m)), "wrong_width": np.zeros((n, m + 1)),
        "odd_width": np.zeros((n, 3)), "fewer_rows": good[:1], "nan": _with(good, np.nan),
        "inf": _with(good, np.inf), "neg_inf": _with(good, -np.inf),
        "huge": _with(good, 1e300), "exploding": Exploding(),
    }
    return cases


def _with(a, value):
    b = a.copy()
    b.flat[len(b.flat) // 2] = value
    return b


def _bad_steps(n):
    return {
        "zero": 0.0, "negative": -0.1, "nan": math.nan, "inf": math.inf, "subnormal": 5e-324,
        "wrong_length": np.full(n + 1, 0.1), "string": "0.1", "none": None, "complex": 0.1j,
        "negative_in_array": np.r_[np.full(n - 1, 0.1), -0.1], "matrix": np.full((n, 2), 0.1),
        "huge": 1e300,
    }


def _expect_refused_or_finite(call, *, must_refuse=False):
    try:
        out = call()
    except RuntimeError as e:  # the caller's own object raised while being read: passed on
        assert str(e) == "boom", f"{type(e).__name__}: {e}"
        return
    except REFUSED as e:
        msg = str(e)
        assert msg.strip(), "a refusal without a message"
        assert "internal error" not in msg and "std::" not in msg, msg
        return
    assert not must_refuse, f"accepted: {out!r}"
    for value in _numbers(out):
        assert np.all(np.isfinite(value)), f"accepted with a non-finite result: {value!r}"


def _numbers(out):
    if isinstance(out, (float, int, np.ndarray)):
        yield np.asarray(out, dtype=float)
    elif isinstance(out, csympnet.Model):
        yield out.params
        if out.gamma is not None:
            yield out.gamma


FIT_CASES = []
for _name, _v in _bad_arrays(Z0.shape).items():
    FIT_CASES.append(pytest.param("z0", _v, id=f"fit-z0-{_name}"))
    FIT_CASES.append(pytest.param("z1", _v, id=f"fit-z1-{_name}"))
for _name, _v in _bad_steps(len(Z0)).items():
    FIT_CASES.append(pytest.param("h", _v, id=f"fit-h-{_name}"))


@pytest.mark.parametrize("which, value", FIT_CASES)
def test_fit_refuses_bad_data(which, value):
    args = {"z0": Z0, "z1": Z1, "h": H}
    args[which] = value
    must = not (which == "h" and np.ndim(value) == 0 and isinstance(value, float)
                and value == 1e300)
    _expect_refused_or_finite(lambda: csympnet.fit(args["z0"], args["z1"], args["h"], epochs=2,
                                                   refine="none", bootstrap=0),
                              must_refuse=must)


OPTION_CASES = [
    ("epochs", v) for v in (0, -1, 1.5, "10", 10**20, True)
] + [
    ("seed", v) for v in (-1, 2**64, 1.5, "1")
] + [
    ("lr", v) for v in (0.0, -1.0, math.nan, math.inf, "0.1", 1e300)
] + [
    ("beta_init", v) for v in (0.0, math.nan, math.inf, "x", 1e300)
] + [
    ("val_fraction", v) for v in (0.0, 1.0, -0.5, math.nan, 2)
] + [
    ("core", v) for v in ("la:0:0", "la:5", "g:1:0", "xx:1:1", 5, {"type": "la"},
                          "la:100000:100000", {"type": "la", "layers": -1, "sublayers": 2})
] + [
    ("refine", v) for v in ("fast", 1, None)
] + [
    ("refine_iterations", v) for v in (0, -5, 1.5)
] + [
    ("refine_solver", v) for v in ("qr", 3)
] + [
    ("bootstrap", v) for v in (-1, 5, 1.5, "100")
] + [
    ("threads", v) for v in (0, -1, 10**6, 1.5)
] + [
    ("model", v) for v in ("hnn", "", None)
] + [
    ("lr_schedule", v) for v in ("step", None)
] + [
    ("progress", v) for v in (3, "print")
]


@pytest.mark.parametrize("option, value", OPTION_CASES,
                         ids=[f"fit-{o}-{v!r}"[:60] for o, v in OPTION_CASES])
def test_fit_refuses_bad_options(option, value):
    kwargs = {"epochs": 2, "refine": "none", "bootstrap": 0}
    kwargs[option] = value
    if option == "beta_init":
        kwargs["warm_start"] = False  # else the warm start replaces beta_init
    _expect_refused_or_finite(lambda: csympnet.fit(Z0, Z1, H, **kwargs), must_refuse=True)


def _trajectory(n=40, d=1):
    t = np.cumsum(np.r_[0.0, np.full(n - 1, 0.1)])
    z = np.c_[np.cos(t), -np.sin(t)] * np.exp(-0.05 * t)[:, None]
    return z, t


IDENTIFY_CASES = []
_z, _t = _trajectory()
for _name, _v in _bad_arrays(_z.shape).items():
    IDENTIFY_CASES.append(pytest.param(_v, _t, id=f"identify-z-{_name}"))
for _name, _v in {
        "repeated": np.r_[_t[:5], _t[4:-1]], "decreasing": _t[::-1], "nan": _with(_t, np.nan),
        "short": _t[:-3], "string": "t", "none": None, "two_d": _t[:, None] * np.ones(2),
        "subnormal_steps": _t * 1e-320}.items():
    IDENTIFY_CASES.append(pytest.param(_z, _v, id=f"identify-t-{_name}"))


@pytest.mark.parametrize("z, t", IDENTIFY_CASES)
def test_identify_refuses_bad_trajectories(z, t):
    _expect_refused_or_finite(lambda: csympnet.identify(z, t, epochs=5, lm_iterations=1),
                              must_refuse=True)


@pytest.fixture(scope="module")
def small_model():
    return csympnet.fit(Z0, Z1, H, epochs=2, refine="none", bootstrap=0, core="la:1:2")


MODEL_CASES = []
for _name, _v in _bad_arrays((3, 2)).items():
    if _name in ("fewer_rows", "huge"):
        continue  # one state, or large finite states: valid inputs
    if _name == "empty":  # an empty batch gives an empty answer, as in NumPy; rollout refuses
        MODEL_CASES.append(pytest.param("rollout", _v, 0.1, id=f"rollout-z0-{_name}"))
        continue
    MODEL_CASES.append(pytest.param("predict", _v, 0.1, id=f"predict-z-{_name}"))
    MODEL_CASES.append(pytest.param("jacobian", _v, 0.1, id=f"jacobian-z-{_name}"))
    MODEL_CASES.append(pytest.param("rollout", _v, 0.1, id=f"rollout-z0-{_name}"))
for _name, _v in _bad_steps(3).items():
    if _name == "huge":
        continue
    MODEL_CASES.append(pytest.param("predict", np.zeros((3, 2)), _v, id=f"predict-h-{_name}"))
    MODEL_CASES.append(pytest.param("jacobian", np.zeros((3, 2)), _v, id=f"jacobian-h-{_name}"))


@pytest.mark.parametrize("method, z, h", MODEL_CASES)
def test_model_methods_refuse_bad_input(small_model, method, z, h):
    call = {
        "predict": lambda: small_model.predict(z, h),
        "jacobian": lambda: small_model.jacobian(z, h),
        "rollout": lambda: small_model.rollout(z, h, steps=3),
    }[method]
    _expect_refused_or_finite(call, must_refuse=True)


def test_views_do_not_change_answers(small_model):
    """A non-contiguous, reversed or read-only view is read as the values it shows."""
    z = RNG.uniform(-1, 1, (6, 4))[:, ::2]
    ro = np.ascontiguousarray(z)
    ro.setflags(write=False)
    want = small_model.predict(np.ascontiguousarray(z), 0.1)
    assert np.array_equal(small_model.predict(z, 0.1), want)
    assert np.array_equal(small_model.predict(ro, 0.1), want)
    assert np.array_equal(small_model.predict(np.asfortranarray(z), 0.1), want)


FILE_CASES = {
    "missing": None, "directory": "DIR", "empty": "", "garbage": "\x00\x01\x02",
    "json_list": "[1, 2]", "truncated": "{\"format\": \"csympnet-model\", \"vers",
    "wrong_format": "{\"format\": \"x\"}", "huge_number": "{\"format\": 1e999}",
    "repeated_key": "{\"format\": \"csympnet-model\", \"format\": \"csympnet-model\"}",
}


@pytest.mark.parametrize("kind", sorted(FILE_CASES))
def test_load_refuses_bad_files(tmp_path, kind):
    text = FILE_CASES[kind]
    path = tmp_path / "model.json"
    if text == "DIR":
        path.mkdir()
    elif text is not None:
        path.write_text(text)
    _expect_refused_or_finite(lambda: csympnet.load(path), must_refuse=True)
    if text not in (None, "DIR"):
        _expect_refused_or_finite(lambda: csympnet.from_json(text), must_refuse=True)


def test_edited_model_files_are_refused(tmp_path, small_model):
    text = small_model.to_json()
    assert np.array_equal(csympnet.from_json(text).params, small_model.params)
    for old, new in (("\"version\": 2", "\"version\": 1"), ("\"version\": 2", "\"version\": 3")):
        assert old in text
        with pytest.raises(ValueError):
            csympnet.from_json(text.replace(old, new, 1))
    digits = [i for i, c in enumerate(text) if c.isdigit()]
    for i in digits[len(digits) // 2: len(digits) // 2 + 20]:
        edited = text[:i] + str((int(text[i]) + 1) % 10) + text[i + 1:]
        try:
            loaded = csympnet.from_json(edited)
        except ValueError:
            continue
        # Accepted only where the edit does not change the number read (a 17th digit that
        # rounds to the same double): then the model is the original, to the bit.
        assert loaded.to_json() == text, f"an edit at {i} changed the model and was accepted"


# --- files, paths and signals ---------------------------------------------------------------
# (docs/hardening.md, "Special files", "Parser memory", "Integrator bounds", "Signals")

def _writers(small_model, pairs):
    return {
        "Model.save": lambda p: small_model.save(p),
        "write_csv": lambda p: csympnet.write_csv(p, pairs),
    }


@pytest.fixture(scope="module")
def pairs():
    return csympnet.Pairs(Z0, Z1, np.full(len(Z0), H))


@pytest.mark.parametrize("writer", ["Model.save", "write_csv"])
def test_writes_refuse_fifos_devices_and_symlinks(tmp_path, small_model, pairs, writer):
    """An atomic rename would turn the node into a regular file (/dev/null, as root, became
    one): each is refused by name and stays what it was."""
    write = _writers(small_model, pairs)[writer]
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    with pytest.raises(csympnet.Error, match=r"fifo.*FIFO.*expected a regular file"):
        write(fifo)
    assert stat.S_ISFIFO(os.lstat(fifo).st_mode)
    target = tmp_path / "target.txt"
    target.write_text("mine\n")
    link = tmp_path / "link"
    link.symlink_to(target)
    with pytest.raises(csympnet.Error, match="symbolic link"):
        write(link)
    assert link.is_symlink() and target.read_text() == "mine\n"
    (tmp_path / "dir").mkdir()
    with pytest.raises(csympnet.Error, match="directory"):
        write(tmp_path / "dir")
    if os.geteuid() == 0:
        null = tmp_path / "null"
        os.mknod(null, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
        with pytest.raises(csympnet.Error, match="character device"):
            write(null)
        assert stat.S_ISCHR(os.lstat(null).st_mode)
    assert not [p for p in os.listdir(tmp_path) if ".tmp." in p], "a temporary was left"


def test_nul_bytes_in_paths_are_refused_as_python_refuses_them(tmp_path, small_model, pairs):
    """A NUL byte cut the path short: 'a\\x00b' wrote 'a'. Every path argument refuses it."""
    small_model.save(tmp_path / "a")
    (tmp_path / "d.csv").write_text("h,q1,p1,next_q1,next_p1\n0.1,1,0,0.9,0.1\n")
    bad = str(tmp_path / "a") + "\x00b"
    calls = {
        "save": lambda: small_model.save(str(tmp_path / "new") + "\x00b"),
        "save_bytes": lambda: small_model.save(os.fsencode(str(tmp_path / "new")) + b"\x00b"),
        "load": lambda: csympnet.load(bad),
        "read_csv": lambda: csympnet.read_csv(str(tmp_path / "d.csv") + "\x00x"),
        "write_csv": lambda: csympnet.write_csv(str(tmp_path / "new") + "\x00b", pairs),
        "identify_init": lambda: csympnet.identify(np.zeros((40, 2)), np.arange(40) * 0.1,
                                                   init=bad),
    }
    for name, call in calls.items():
        with pytest.raises(ValueError, match="embedded null byte"):
            call()
    assert not (tmp_path / "new").exists()
    # The C++ layer refuses it too (a caller of the compiled module directly).
    with pytest.raises(ValueError, match="null byte"):
        csympnet._core.load(bad)


def test_model_text_beyond_what_a_model_holds_is_refused(small_model):
    """A model file's meta is bounded while it is parsed (a 15-million-entry array took 20
    times its size in memory); so is its nesting depth."""
    text = small_model.to_json()
    big = '{"meta": {"junk": [' + ",".join(["0"] * 1_000_001) + ']},' + text.lstrip()[1:]
    with pytest.raises(csympnet.Error, match="values outside \"params\""):
        csympnet.from_json(big)
    deep = '{"meta": ' + "[" * 100 + "]" * 100 + "}"
    with pytest.raises(csympnet.Error, match="nested deeper than 64"):
        csympnet.from_json(deep)


def test_nan_parameters_are_named_as_nan(small_model):
    spec = json.dumps(json.loads(small_model.to_json())["model"])
    params = small_model.params.copy()
    params[1] = np.nan
    with pytest.raises(csympnet.Error, match=r"params\[1\] is nan; expected finite"):
        csympnet._core.from_spec(spec, params, "{}")


@pytest.fixture(scope="module")
def ode_model():
    return csympnet.run("s1", "ode", epochs=1).model


def test_ctrl_c_stops_a_vector_field_prediction_over_a_huge_step(ode_model):
    """dopri5 integrates the whole span: predict(z, 1e12) ran for hours, deaf to Ctrl-C."""
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            ode_model.predict(np.array([0.1, 0.2]), 1e12)
        stopped = time.monotonic() - start
    finally:
        timer.cancel()
    assert stopped < 1.5, f"stopped {stopped - 0.5:.2f} s after SIGINT"
    # The next call is not stopped by the old signal.
    assert np.all(np.isfinite(ode_model.predict(np.array([0.1, 0.2]), 0.1)))


# --- the Hamiltonian-library core ------------------------------------------------------------

def _oscillator(n=60, h=0.1, gamma=0.1):
    t = np.arange(n) * h
    e = np.exp(-0.5 * gamma * t)
    return np.stack([e * np.cos(t), -e * np.sin(t)], axis=1), t


def _library_spec(**core):
    return {"type": "csympnet", "d": 1,
            "core": {"type": "library", "terms": ["q1^2", "q1^4"], **core}}


def _library_model(params=(1.0, 0.5, 0.0, 0.1), **core):
    """A library model through the model file's own reader (W, c(q1^2), c(q1^4), beta)."""
    return csympnet.Model(csympnet._core.from_spec(json.dumps(_library_spec(**core)),
                                                   np.array(params, dtype=float), "{}"))


def _file_refusal(core):
    spec = {"type": "csympnet", "d": 1, "core": core}
    with pytest.raises(csympnet.Error) as e:
        csympnet._core.from_spec(json.dumps(spec), np.ones(4), "{}")
    return str(e.value)


@pytest.mark.parametrize("name", ["q" + "1" * 50000, "sin(q" + "1" * 50000 + ")",
                                  "q99999999999999999999", "(q1-q99999999999999999999)^2"])
def test_library_term_names_of_any_length_are_refused_by_name(name):
    """A name of 50,000 digits crashed the interpreter (SIGSEGV in std::regex); 20 digits
    raised an IndexError (std::stol's out_of_range)."""
    shown = name if len(name) <= 40 else name[:40] + "\u2026"
    message = _file_refusal({"type": "library", "terms": [name]})
    assert f"term '{shown}': coordinate" in message and "out of range" in message
    assert len(message) < 600
    z, t = _oscillator()
    with pytest.raises(csympnet.Error, match="out of range") as e:
        csympnet.identify(z, t, core={"type": "library", "terms": [name]})
    assert f"core.terms: term '{shown}'" in str(e.value)


# The core dicts the model-file reader refuses; identify() refused none of them but the terms.
BAD_LIBRARY_CORES = {
    "order_3": {"type": "library", "terms": ["q1^2"], "order": 3},
    "mass_heavy": {"type": "library", "terms": ["q1^2"], "mass": "heavy"},
    "negative_scale": {"type": "library", "terms": ["q1^2"], "coordinate_scales": [-1]},
    "unknown_key": {"type": "library", "terms": ["q1^2"], "wavenumbers": 2},
    "terms_as_dict": {"type": "library", "terms": {"q1^2": 1}},
    "terms_empty": {"type": "library", "terms": []},
    "term_a_number": {"type": "library", "terms": [5]},
    "substeps_zero": {"type": "library", "terms": ["q1^2"], "substeps": 0},
}


@pytest.mark.parametrize("case", sorted(BAD_LIBRARY_CORES))
def test_a_given_library_core_is_refused_as_a_model_file_refuses_it(case):
    """One reading of the core (read_library_spec): the same refusal in the same words."""
    core = BAD_LIBRARY_CORES[case]
    in_file = _file_refusal(core)
    z, t = _oscillator()
    with pytest.raises(csympnet.Error) as e:
        csympnet.identify(z, t, core=core)
    assert str(e.value).startswith("core")
    # "model: model spec.core…" from the file, "core…" from identify: the rest is the same.
    assert in_file.split("model spec.core", 1)[1] == str(e.value)[len("core"):]


@pytest.mark.parametrize("key, value", [("order", 4), ("substeps", 10**7), ("mass", "diagonal"),
                                        ("coordinate_scales", [2.0])])
def test_identify_refuses_library_keys_it_would_ignore(key, value):
    """Valid in a model file, chosen by the identification itself: refused, not ignored."""
    z, t = _oscillator()
    with pytest.raises(csympnet.Error, match=f"core: key '{key}' is chosen by the identification"):
        csympnet.identify(z, t, core={"type": "library", "terms": ["q1^2"], key: value})


@pytest.mark.parametrize("key, value, said", [
    ("derived_momenta", None, "derived_momenta: got null; expected a string"),
    ("derived_momenta", 3, "derived_momenta: got 3; expected a string"),
])
def test_identify_names_a_setting_of_the_wrong_kind(key, value, said):
    """A raw json.exception.type_error.302 named neither the key nor what was expected."""
    z, t = _oscillator()
    with pytest.raises(csympnet.Error) as e:
        csympnet.identify(z, t, **{key: value})
    assert said in str(e.value)
    assert "type_error" not in str(e.value)


@pytest.mark.parametrize("mass, params, said", [
    ("full", (0.0, 0.5, 0.0, 0.1), r"params\[0\] = 0 is W\[1,1\]"),
    ("diagonal", (-1.0, 0.5, 0.0, 0.1), r"params\[0\] = -1 is W\[1,1\]"),
])
def test_a_library_model_with_a_non_positive_inverse_mass_is_refused(mass, params, said):
    """It loaded and rolled out without a word."""
    with pytest.raises(csympnet.Error, match=said + r".*expected a positive inverse mass"):
        _library_model(params, mass=mass)
    assert np.isfinite(_library_model((1.0, 0.5, 0.0, 0.1), mass=mass).rollout(
        np.array([0.1, 0.2]), np.full(3, 0.1))).all()


def test_ctrl_c_stops_a_library_rollout_of_many_substeps():
    """4,000,000 substeps of order 6 a step: Model.rollout ran to its end after SIGINT."""
    model = _library_model(substeps=4_000_000, order=6)
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            model.rollout(np.array([0.1, 0.2]), np.full(100, 0.1))
        stopped = time.monotonic() - start
    finally:
        timer.cancel()
    assert stopped < 1.5, f"stopped {stopped - 0.5:.2f} s after SIGINT"


def test_the_suite_has_at_least_two_hundred_cases():
    n = (len(FIT_CASES) + len(OPTION_CASES) + len(IDENTIFY_CASES) + len(MODEL_CASES)
         + len(FILE_CASES))
    assert n >= 200, n
