"""Systems, the paper's presets, data generation and CSV files."""

import json

import numpy as np

from . import _checks, _core, _records
from ._records import Pairs, Trajectory

REFERENCES = ("splitting", "expm", "rk")


def _preset_info(name):
    return json.loads(_core.preset_json(name))


#: The paper's presets, by name ("s1", "s2", "s3", "s2-100", "s3-100"): each a dict with the
#: system ("kind", "d", "gamma", "omega", "k", "alpha"), data sizes ("n_train", "n_val",
#: "n_test"), training steps ("train_steps": {"h_min", "h_max"}), "h_test", "horizon", the
#: symplectic "core" and the default training recipe (docs/protocol.md, "Presets").
systems = {name: _preset_info(name) for name in _core.preset_names()}


def model_types():
    """Every model type the library knows: csympnet, sympnet, map, ode, dhnn, dhnn2, phnn, phnn2."""
    return list(_core.model_types())


class System:
    """A linearly damped Hamiltonian system dq/dt = ∂H/∂p, dp/dt = −∂H/∂q − γp,
    H = ½‖p‖² + V(q), of one of the library's kinds (systems/system.hpp):

    - "oscillator": V = ½ω²‖q‖²
    - "chain": V = (k/2) Σ (q_{i+1} − q_i)², free ends
    - "cubic": V = ½ω²‖q‖² + α (Σ q_i)³

    >>> System(kind="oscillator", d=1, gamma=0.1).energy([1.0, 0.0])
    array([0.5])
    """

    def __init__(self, kind="oscillator", d=1, gamma=0.05, omega=1.0, k=1.0, alpha=0.005):
        spec = {"kind": kind, "d": d, "gamma": gamma, "omega": omega, "k": k, "alpha": alpha}
        self._json = _core.check_system(json.dumps(spec))
        self.spec = json.loads(self._json)

    @classmethod
    def preset(cls, name):
        """The system of a preset (see `csympnet.systems`)."""
        _checks.choice("preset", name, tuple(systems))
        return cls(**systems[name]["system"])

    @classmethod
    def from_spec(cls, spec):
        """From a dict of fields as in `System.spec` ("kind" and "d" required)."""
        if isinstance(spec, System):
            return spec
        if not isinstance(spec, dict):
            raise TypeError(
                f"system: expected a csympnet.System or a dict, got {type(spec).__name__}")
        unknown = set(spec) - {"kind", "d", "gamma", "omega", "k", "alpha"}
        if unknown:
            raise ValueError(
                f"system: unknown field(s) {sorted(unknown)}; "
                "expected kind, d, gamma, omega, k, alpha"
            )
        if "kind" not in spec or "d" not in spec:
            raise ValueError("system: expected at least the fields 'kind' and 'd'")
        return cls(**spec)

    @property
    def d(self):
        return self.spec["d"]

    @property
    def gamma(self):
        return self.spec["gamma"]

    def energy(self, z):
        """H at each state: z (2d,) or (N, 2d) → (N,)."""
        a, _ = _checks.states("z", z, dim=2 * self.d)
        return _core.energy(self._json, a)

    def vector_field(self, z):
        """The damped vector field f(z) at each state: (N, 2d) (a single state gives (2d,))."""
        a, single = _checks.states("z", z, dim=2 * self.d)
        f = _core.vector_field(self._json, a)
        return f[0] if single else f

    def flow(self, z, h, reference="splitting"):
        """The reference solution Φ_h(z) (integrators/reference.hpp): the conformal
        Störmer–Verlet splitting with substeps ≤ 1e-3 ("splitting", the data's solver), the
        exact matrix exponential ("expm", linear kinds) or tight adaptive Runge–Kutta ("rk")."""
        a, single = _checks.states("z", z, dim=2 * self.d)
        hs = _checks.steps("h", h, a.shape[0])
        _checks.choice("reference", reference, REFERENCES)
        out = _core.flow(self._json, a, hs, reference)
        return out[0] if single else out

    def __repr__(self):
        order = ("kind", "d", "gamma", "omega", "k", "alpha")
        fields = ", ".join(f"{k}={self.spec[k]!r}" for k in order)
        return f"csympnet.System({fields})"


def _system_overrides(system):
    if system is None:
        return "null"
    if isinstance(system, System):
        return json.dumps(system.spec)
    if not isinstance(system, dict):
        raise TypeError(
            "system: expected a dict of system fields or a csympnet.System, got "
            f"{type(system).__name__}"
        )
    return json.dumps(system)


def generate(preset="s1", split="train", *, seed=None, n=None, sigma=0.0, h=None,
             reference="splitting", system=None):
    """The data of a preset, exactly as `csympnet generate` (and `csympnet run`) make them.

    preset: one of `csympnet.systems`.
    split: "train" or "val" → `Pairs` (z0 (N, 2d), z1 (N, 2d), h (N,)); "test" → a list of
        `Trajectory` (t (n+1,), z (n+1, 2d)) on the uniform grid of step h_test.
    seed: training seed for train/val (default 42); data seed for test (default 0).
    n: number of pairs or trajectories (default: the preset's).
    sigma: relative observation noise on train/val pairs (docs/protocol.md, "Noise").
    h: step of the pairs, a number or a range (h_min, h_max) drawn uniformly per pair
        (default: the preset's).
    reference: "splitting" (default), "expm" (linear kinds) or "rk".
    system: dict of system fields that replace the preset's (e.g. {"gamma": 0.1, "d": 3}), or a
        csympnet.System.
    """
    _checks.choice("preset", preset, tuple(systems))
    _checks.choice("split", split, ("train", "val", "test"))
    _checks.choice("reference", reference, REFERENCES)
    seed_given = seed is not None
    seed = 42 if seed is None else _checks.seed("seed", seed)
    if n is not None:
        n = _checks.integer("n", n, minimum=1)
    sigma = _checks.real("sigma", sigma, nonnegative=True)
    if h is not None:
        if np.ndim(h) == 0:
            h = (_checks.real("h", h, positive=True),) * 2
        else:
            lo, hi = (_checks.real("h", x, positive=True) for x in _checks.vector("h", h, length=2))
            if lo > hi:
                raise ValueError(f"h: expected (h_min, h_max) with h_min <= h_max, got {(lo, hi)}")
            h = (lo, hi)
    out = _core.generate(preset, split, seed, seed_given, n, h, sigma, reference,
                         _system_overrides(system))
    if split == "test":
        return [Trajectory(t, z) for t, z in out[0]]
    return Pairs(*out)


def read_csv(path):
    """Reads a CSV of pairs (→ `Pairs`) or trajectories (→ list of `Trajectory`), with the
    CLI's reader (docs/data-formats.md): bad files raise csympnet.Error naming line and column."""
    kind, data = _core.read_csv(_checks.path("path", path))
    if kind == "pairs":
        return Pairs(*data)
    return [Trajectory(t, z) for t, z in data]


def write_csv(path, data):
    """Writes `Pairs` (pairs format) or a list of `Trajectory` (trajectories format), each
    number as the shortest text that reads back to the same double, so the CLI reads back the
    same bits."""
    path = _checks.path("path", path)
    if isinstance(data, Pairs):
        _core.write_pairs_csv(path, *_records.pairs("", data.z0, data.z1, data.h))
    else:
        _core.write_trajectories_csv(path, _records.trajectory_list(data))
