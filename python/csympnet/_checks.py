"""Argument checks of the public API: one value or one array at a time.

Every check names the argument, says what was found and what was expected, and raises
TypeError (wrong kind of object or dtype) or ValueError (wrong shape or value). What passes is
a float64 C-contiguous array the compiled module can take as it is. Records (trajectories,
pairs, frames, inputs) are read in _records.py, which builds on these.

Only what Python alone can check lives here: the kinds of objects, array shapes and values
before they are converted. The ranges of the options of fit, identify and run, and the rules
between them, are the library's (include/csympnet/core/options.hpp): it refuses a value with
a csympnet.Error that names the argument as Python spells it.
"""

import numbers
import os

import numpy as np


def path(name, p):
    """A file path argument (str, bytes or os.PathLike) → str, refused as Python's own file
    functions refuse it: a NUL byte would cut the path short in the system call."""
    if not isinstance(p, (str, bytes, os.PathLike)):
        raise TypeError(f"{name}: expected a path (str, bytes or os.PathLike), got {type(p).__name__}")
    p = os.fsdecode(os.fspath(p))
    if "\x00" in p:
        raise ValueError("embedded null byte")
    return p


def real_array(name, x):
    """x as a float64 C-order array of any shape, refused unless it holds real numbers."""
    if x is None:
        raise TypeError(f"{name}: expected an array of real numbers, got None")
    try:
        a = np.asarray(x)
    except (ValueError, TypeError) as e:  # ragged nested lists, and the like
        raise ValueError(f"{name}: cannot be read as an array ({e})") from None
    if a.dtype.kind not in "fiu":
        raise TypeError(
            f"{name}: expected real numbers (a float or integer array), got dtype {a.dtype}"
        )
    return np.asarray(a, dtype=np.float64, order="C")


def require_finite(name, a):
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        where = "" if a.ndim == 0 else f" (first at index {tuple(int(i) for i in bad)})"
        raise ValueError(f"{name}: contains NaN or Inf{where}; expected finite values")


def states(name, z, dim=None, allow_single=True):
    """A state (2d,) or a batch (N, 2d) → ((N, 2d) array, whether a single state was given)."""
    a = real_array(name, z)
    single = a.ndim == 1
    if single and allow_single:
        a = a.reshape(1, -1)
    expected = "a state (2d,) or a batch (N, 2d)" if allow_single else "a batch (N, 2d)"
    if a.ndim != 2:
        raise ValueError(f"{name}: expected {expected}, got an array of shape {np.shape(z)}")
    width = a.shape[1]
    if dim is not None and width != dim:
        raise ValueError(
            f"{name}: states have {width} components, expected 2d = {dim} (q1..qd, p1..pd)"
        )
    if width == 0 or width % 2 != 0:
        raise ValueError(
            f"{name}: states have {width} components; expected an even number 2d >= 2 "
            "(q1..qd, p1..pd)"
        )
    require_finite(name, a)
    return a, single


def vector(name, x, length=None, min_length=0):
    """A 1-D array of finite reals."""
    a = real_array(name, x)
    if a.ndim != 1:
        raise ValueError(f"{name}: expected a 1-D array, got shape {a.shape}")
    if length is not None and a.shape[0] != length:
        raise ValueError(f"{name}: has {a.shape[0]} entries, expected {length}")
    if a.shape[0] < min_length:
        raise ValueError(f"{name}: has {a.shape[0]} entries, expected at least {min_length}")
    require_finite(name, a)
    return a


def steps(name, h, n):
    """Steps h > 0: a scalar (the same for all n) or an array of n → (n,) array."""
    a = real_array(name, h)
    if a.ndim == 0:
        a = np.full(n, float(a))
    elif a.ndim != 1 or a.shape[0] != n:
        raise ValueError(f"{name}: expected a scalar or an array of {n} steps, got shape {a.shape}")
    require_finite(name, a)
    if n and not np.all(a > 0):
        raise ValueError(f"{name}: expected steps > 0, got {a[a <= 0][0]!r}")
    tiny = a < np.finfo(np.float64).tiny
    if np.any(tiny):
        raise ValueError(
            f"{name}: step {a[tiny][0]!r} is below the smallest normal double (2.2e-308), where "
            "exp(-gamma h) and h-polynomials lose their precision; expected a rescaled time unit")
    return a


def real(name, x, positive=False, nonnegative=False):
    """A finite real scalar."""
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, numbers.Real):
        raise TypeError(f"{name}: expected a real number, got {type(x).__name__}")
    x = float(x)
    if not np.isfinite(x):
        raise ValueError(f"{name}: expected a finite number, got {x}")
    if positive and x <= 0:
        raise ValueError(f"{name}: expected a number > 0, got {x}")
    if nonnegative and x < 0:
        raise ValueError(f"{name}: expected a number >= 0, got {x}")
    return x


def integer(name, x, minimum=None, maximum=2**63 - 1):
    """An integer (not a bool) in [minimum, maximum]; the default maximum fits a C++ long."""
    if isinstance(x, (bool, np.bool_)) or not isinstance(x, numbers.Integral):
        raise TypeError(f"{name}: expected an integer, got {type(x).__name__}")
    x = int(x)
    if minimum is not None and x < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {x}")
    if x > maximum:
        raise ValueError(f"{name}: expected an integer <= {maximum}, got {x}")
    return x


def seed(name, x):
    """A seed: an integer in [0, 2^64)."""
    return integer(name, x, minimum=0, maximum=2**64 - 1)


def choice(name, x, options):
    """One of `options` (strings)."""
    if not isinstance(x, str):
        raise TypeError(f"{name}: expected a string, one of {', '.join(options)}")
    if x not in options:
        raise ValueError(f"{name}: expected one of {', '.join(options)}, got {x!r}")
    return x
