"""csympnet.Model: a trained model, and csympnet.load."""

import json

import numpy as np

from . import _checks, _core, _records
from ._data import System, systems
from ._records import OBSERVED, Trajectory

# Test sets generated when diagnostics() gets no trajectories: the presets' common values
# (docs/protocol.md, "Test trajectories": 10 trajectories on [0, 10] with h_test = 0.2, data
# seed 0).
_DEFAULT_N_TEST = 10
_DEFAULT_H_TEST = 0.2
_DEFAULT_HORIZON = 10.0


class Model:
    """A trained model of any type: a one-step map (csympnet, sympnet, map) or a vector field
    whose one-step map is induced by dopri5 integration (ode, dhnn, dhnn2, phnn, phnn2).

    Made by `csympnet.fit`, `csympnet.fit_trajectories`, `csympnet.run` or `csympnet.load`.
    States are rows: a state is an array (2d,) = (q1..qd, p1..pd), a batch is (N, 2d).

    Attributes:
        meta: dict saved with the model (its context: seed, training recipe, system, ...).
            Add "system" (a dict as in `csympnet.System.spec`) so that `csympnet evaluate`
            and `Model.diagnostics()` know the system without being told.
    """

    def __init__(self, core_model):
        if not isinstance(core_model, _core.Model):
            raise TypeError("csympnet.Model is made by csympnet.fit, fit_trajectories, run or load")
        self._m = core_model
        self.meta = json.loads(core_model.meta_json)

    # --- what the model is -------------------------------------------------------------
    @property
    def type(self):
        """Model type: "csympnet", "sympnet", "map", "ode", "dhnn", "dhnn2", "phnn" or "phnn2"."""
        return self._m.type

    @property
    def d(self):
        """Degrees of freedom d (states have 2d components)."""
        return self._m.dim // 2

    @property
    def n_params(self):
        return self._m.n_params

    @property
    def params(self):
        """A copy of the flat parameter vector θ (layout: docs/derivations.md)."""
        return self._m.params

    @property
    def hyperparams(self):
        """The architecture as a dict (the "model" entry of a model file)."""
        return json.loads(self._m.hyperparams_json)

    @property
    def gamma(self):
        """The identified damping rate γ̂ = |β| (csympnet, dhnn2, phnn2), else None."""
        return self._m.gamma

    @property
    def gamma_interval(self):
        """(low, high) interval for γ̂ when the fit computed one, else None."""
        return self._m.gamma_interval

    @property
    def training(self):
        """Summary of the training run in this process (epochs_run, best_epoch, best_val_loss,
        final_train_loss, seconds, stop_reason), or None for a loaded model."""
        if hasattr(self, "_training"):  # unpickled: kept beside the model file
            return self._training
        return json.loads(self._m.training_json)

    # --- pickling: the model file's text (θ to the bit), meta and the training summary -----
    def __getstate__(self):
        return {"model_file": self.to_json(), "training": self.training}

    def __setstate__(self, state):
        self._m = _core.from_json(state["model_file"])
        self.meta = json.loads(self._m.meta_json)
        self._training = state["training"]

    def __repr__(self):
        g = "" if self.gamma is None else f", gamma={self.gamma:.6g}"
        return f"<csympnet.Model {self.type}, d={self.d}, {self.n_params} params{g}>"

    # --- the map ---------------------------------------------------------------------------
    def predict(self, z, h, batched=False):
        """One step z ↦ Φ̂_h(z).

        z: a state (2d,) or a batch (N, 2d); h: a step > 0, or one per state (N,).
        Returns an array of z's shape. Each state is stepped on its own, exactly as
        `csympnet rollout` steps it (same bits). batched=True evaluates a map model's batch in
        one pass (faster for large N; equal to rounding, ~1e-16). Vector-field models integrate
        each state with dopri5 (rtol 1e-7, atol 1e-9).
        """
        a, single = _checks.states("z", z, dim=2 * self.d)
        hs = _checks.steps("h", h, a.shape[0])
        out = self._m.predict(a, hs, bool(batched))
        return out[0] if single else out

    def rollout(self, z0, hs, steps=None):
        """Iterates the map from z0: ẑ_0 = z0, ẑ_{n+1} = Φ̂_{h_n}(ẑ_n).

        z0: a state (2d,), or a batch (M, 2d).
        hs: the steps h_0..h_{n-1} as an array (n,), or one step h with `steps=n`.
        Returns (n+1, 2d) including z0 (for a batch: (M, n+1, 2d)). If the learned dynamics
        leave the finite numbers, that state and all later ones are +inf. This is the rollout
        of `csympnet rollout` and `csympnet evaluate`, to the bit.
        """
        a, single = _checks.states("z0", z0, dim=2 * self.d)
        if a.shape[0] == 0:
            raise ValueError("z0: expected a state (2d,) or a non-empty batch (M, 2d)")
        if steps is None:
            if np.ndim(hs) == 0:
                raise ValueError("hs: a single step needs steps=n (or pass an array of n steps)")
            h = _checks.vector("hs", hs)
            h = _checks.steps("hs", h, h.shape[0])
        else:
            n = _checks.integer("steps", steps, minimum=0)
            h = _checks.steps("hs", _checks.real("hs", hs, positive=True), n)
        out = np.stack([self._m.rollout(row, h) for row in a])
        return out[0] if single else out

    @property
    def n_inputs(self):
        """The number m of known inputs the map reads (0: a free model)."""
        return int(self._m.n_inputs)

    def simulate(self, z0, t, u):
        """The free run of a driven model from the state z0 at t[0], fed the known inputs u
        (n, m) at the times t (n,), held between samples as the model holds them (its
        "hold"): an array (n, 2d) whose first row is z0. The simulation of `csympnet evaluate`,
        to the bit. z0 from `state_from_positions(q, t, u=...)` of a recent window."""
        if self.n_inputs == 0:
            raise ValueError("simulate: this model has no inputs (it was fitted to a free "
                             "record); use rollout")
        z = _checks.vector("z0", z0, length=2 * self.d)
        ta = _checks.vector("t", t, min_length=2)
        ua = np.asarray(u, dtype=float)
        if ua.ndim == 1 and self.n_inputs == 1:
            ua = ua[:, None]
        return self._m.simulate(z, ta, ua)

    def frequency_response(self, omega, h, *, equilibrium=None, amplitude=None, input_index=0):
        """The frequency response of a driven model sampled at the step h (the step it was
        fitted at). Without `amplitude`: the map linearised at its equilibrium, a dict with
        "omega", "response" (n, d, m) complex (q_i per unit of input j, the data's units),
        "equilibrium" and "modes" [(angular frequency, damping ratio)]. With `amplitude`: the
        nonlinear map driven by amplitude·sin(ωt) on input `input_index`, simulated until it
        repeats, its fundamental per unit of input: "response" (n, d) and "settled" (n,).
        csympnet.plot.frequency_response draws both (docs/identification.md, "The frequency
        response")."""
        from . import _response
        if self.n_inputs == 0:
            raise ValueError("frequency_response: this model has no inputs (it was fitted to a "
                             "free record)")
        step = _checks.real("h", h, positive=True)
        if amplitude is None:
            return _response.linear(self, omega, step, equilibrium)
        return _response.simulated(self, omega, _checks.real("amplitude", amplitude,
                                                             positive=True),
                                   step, input_index=_checks.integer("input_index", input_index,
                                                                     minimum=0),
                                   z_eq=equilibrium)

    def state_from_positions(self, q, t, u=None):
        """The state at the last of a recent window of positions alone, for a prediction or a
        rollout from a record without momenta (a csympnet model, as `fit` writes it).

        q: the positions (L, d), or (L,) for d = 1, L >= 2; t: their times (L,), increasing.
        The window's start momenta are fitted with the model's map (as the held-out segments
        of a positions-only fit), and the fitted motion is carried to t[-1]. Returns
        (state (2d,), rms) with rms the root-mean-square position residual of that fit: near
        the noise of the positions when the model explains the window. The momenta are in the
        units the fit chose for them. `model.rollout(state, h, steps=n)` then forecasts from
        t[-1]; `csympnet rollout --from-positions` does the same. A driven model takes the
        window's inputs u (L, m), and `model.simulate(state, t_next, u_next)` forecasts."""
        qa = _records.positions("q", q, dim=self.d)
        if qa.shape[0] < 2:
            raise ValueError("q: expected at least 2 positions")
        ta = _checks.vector("t", t, length=qa.shape[0])
        if not np.all(np.diff(ta) > 0):
            raise ValueError("t: expected strictly increasing times")
        if u is None:
            state, rms = self._m.state_from_positions(qa, ta)
        else:
            ua = np.asarray(u, dtype=float)
            if ua.ndim == 1 and self.n_inputs == 1:
                ua = ua[:, None]
            state, rms = self._m.state_from_positions(qa, ta, ua)
        return state[0], float(rms)

    def jacobian(self, z, h):
        """The exact input Jacobian DΦ̂_h(z): (2d, 2d) for a state, (N, 2d, 2d) for a batch, with
        J[r, c] = ∂Φ̂_r/∂z_c. Map models: forward-mode, exact; vector-field models: the
        variational equation integrated with the flow."""
        a, single = _checks.states("z", z, dim=2 * self.d)
        hs = _checks.steps("h", h, a.shape[0])
        out = self._m.jacobian(a, hs)
        return out[0] if single else out

    def structure(self, z, h, gamma_true=None):
        """Conformal-structure diagnostics at each state (diagnostics/diagnostics.hpp), with
        M = DΦ̂_h(z) and J = [[0, I], [−I, 0]]:

        - "lambda_hat": λ̂ = ⟨MᵀJM, J⟩_F / ‖J‖_F², the map's conformal factor there;
        - "structure_residual": S = ‖MᵀJM − λ_own J‖_F, λ_own = exp(−γ̂h) (or λ̂ without γ̂),
          zero up to rounding for an exactly conformally symplectic map;
        - "R": ‖MᵀJM − λ* J‖_F with λ* = exp(−γ h) for the true `gamma_true` (NaN without it).

        Returns a dict of arrays (N,) (scalars for a single state).
        """
        a, single = _checks.states("z", z, dim=2 * self.d)
        hs = _checks.steps("h", h, a.shape[0])
        if gamma_true is not None:
            gamma_true = _checks.real("gamma_true", gamma_true, nonnegative=True)
        r, lam, s = self._m.structure(a, hs, gamma_true)
        out = {"R": r, "lambda_hat": lam, "structure_residual": s}
        return {k: v[0] for k, v in out.items()} if single else out

    def score(self, z, t, traj=None, *, observed=None, warmup=None):
        """Scores the model against observed trajectories, with no system needed (what
        `csympnet evaluate --model M --data traj.csv` reports under "observed", or under
        "positions" for a record of positions alone).

        z, t, traj: trajectories in the forms `identify` and `fit_trajectories` take (z (M, 2d)
        with t (M,); rows labelled by traj; z (K, M, 2d); lists of arrays), in the model's units.
        Returns a dict: one_step_rmse, one_step_relative (error over the increment's size),
        one_step_r2 (R² of the increments), rollout_rmse, rollout_nrmse (over each trajectory's
        spread), l2_error (the paper's rollout error), valid_time_mean and valid_fraction_mean
        (how long each rollout from its first state stays within 10% of the trajectory's RMS
        spread), rollout_finite, structure_residual_mean/max (exactness at the observed states),
        gamma_hat, per_trajectory (a list of dicts), and "rollouts" (arrays (n+1, 2d)).
        Definitions: include/csympnet/diagnostics/observed.hpp.

        observed: "states" or "positions"; not given, z with d columns (or (M,) for d = 1) is
        positions and z with 2d columns is states (the model's d tells them apart).

        observed="positions": z holds positions alone, (M, d) in the same forms (a csympnet
        model, as `fit` writes it). For each trajectory the state at sample warmup − 1 is fitted
        to its first `warmup` positions (as `state_from_positions`, which refuses a window with a
        gap or one the model does not explain), the map is rolled out from there one step per
        sample interval, and the positions after the warm-up are scored. warmup: samples, at
        least 3; default a tenth of each trajectory's samples, at least 10 and at most 80; a
        trajectory not longer than its warm-up is refused. Returns the dict `csympnet evaluate`
        reports under "positions", to the bit: trajectories, warmup (None for the default),
        samples_scored, rmse and rmse_per_coordinate (in the data's units), spread and
        spread_per_coordinate (of the scored positions about each trajectory's mean), nrmse
        (rmse / spread), rollout_finite, per_trajectory (samples, warmup, scored, t_start,
        state_fit_rms, rmse, rmse_per_coordinate, spread, rollout_finite), and "rollouts"
        (arrays (n − warmup + 1, 2d): the fitted state at t_start, then the forecast at each
        scored sample). Definitions: include/csympnet/diagnostics/positions_score.hpp.
        """
        if observed is None:
            observed = _records.observed_by_width(z, self.d)
        else:
            _checks.choice("observed", observed, OBSERVED)
        if observed == "states" and warmup is not None:
            raise ValueError('warmup: the warm-up window of positions alone; with states the '
                             'rollout starts from the first observed state (expected '
                             'observed="positions" with warmup=)')
        if warmup is not None:
            warmup = _checks.integer("warmup", warmup)
        width = self.d if observed == "positions" else 2 * self.d
        data = _records.trajectories(z, t, traj, observed=observed, name="data", dim=width)
        return self._score(data, observed, warmup)

    def _score(self, data, observed="states", warmup=None):
        """score() on trajectories already read (_records.py): (t, z) with z of 2d states
        or d positions, as `observed` says."""
        if observed == "states":
            scores, rollouts = self._m.score(data)
        else:
            scores, rollouts = self._m.score_positions(data, warmup)
        out = json.loads(scores)
        out["rollouts"] = list(rollouts)
        return out

    def diagnostics(self, system=None, tests=None, *, preset=None, h_test=None, test_seed=0,
                    n_test=None, horizon=None, per_point=True):
        """The paper's diagnostics against reference test trajectories, as `csympnet evaluate`
        computes them (docs/protocol.md, "Metrics").

        system: the true system, a csympnet.System or a dict of its fields; with `preset`, a
            dict of fields that replace the preset's. Default: the preset's, else the one the
            model file records (meta["system"]).
        tests: reference trajectories, a list of (t, z) (or one); default: generated from the
            system with data seed `test_seed` (the CLI's test set: `n_test` trajectories on
            [0, horizon] with step h_test; defaults 10, 10, 0.2 or the preset's).
        h_test: step of the Jacobian diagnostics (default 0.2 or the preset's).

        Returns a dict: the scalars of `csympnet evaluate` (l2_error, residual_mean,
        residual_max, lambda_hat_mean, lambda_abs_err_mean, lambda_star,
        structure_residual_mean, structure_residual_max, jacobian_points, rollout_finite,
        gamma_hat, gamma_abs_err), gamma_true, h_test, system, and the arrays "tests" (list of
        Trajectory), "rollouts" (list of (n+1, 2d)), "energy_pred" and "energy_ref" (lists of
        (n+1,)); with per_point, "per_point": `structure()` at every test state (dict of arrays).
        """
        sys_obj, h_default, n_default, horizon_default = self._resolve_system(system, preset)
        h_test = h_default if h_test is None else _checks.real("h_test", h_test, positive=True)
        if tests is None:
            n = n_default if n_test is None else _checks.integer("n_test", n_test, minimum=1)
            span = (horizon_default if horizon is None
                    else _checks.real("horizon", horizon, positive=True))
            seed = _checks.seed("test_seed", test_seed)
            trajs, _ = _core.test_set(sys_obj._json, n, h_test, span, seed, "splitting")
            tests = [Trajectory(t, z) for t, z in trajs]
        else:
            tests = _records.trajectory_list(tests, "tests", dim=2 * self.d)
        if sys_obj.d != self.d:
            raise ValueError(f"system: has d = {sys_obj.d}, but the model has d = {self.d}")
        scalars, rollouts, e_pred, e_ref = self._m.evaluate(sys_obj._json, tests, h_test)
        out = json.loads(scalars)
        out.update(gamma_true=sys_obj.gamma, h_test=h_test, system=dict(sys_obj.spec),
                   tests=tests, rollouts=list(rollouts), energy_pred=list(e_pred),
                   energy_ref=list(e_ref))
        if per_point:
            z = np.concatenate([tr.z for tr in tests])
            out["per_point"] = self.structure(z, h_test, gamma_true=sys_obj.gamma)
        return out

    def _resolve_system(self, system, preset):
        if preset is not None:
            _checks.choice("preset", preset, tuple(systems))
            info = systems[preset]
            spec = dict(info["system"])
            if system is not None:
                spec.update(system.spec if isinstance(system, System) else dict(system))
            return System.from_spec(spec), info["h_test"], info["n_test"], info["horizon"]
        if system is None:
            if "system" not in self.meta:
                raise ValueError(
                    "system: this model does not record its system; pass system= (a "
                    "csympnet.System or dict) or preset="
                )
            system = self.meta["system"]
        return System.from_spec(system), _DEFAULT_H_TEST, _DEFAULT_N_TEST, _DEFAULT_HORIZON

    # --- files -----------------------------------------------------------------------------
    def save(self, path):
        """Writes the model file (JSON, io/model_file.hpp; atomically) with `meta`. The CLI reads
        it (`csympnet evaluate --model`, `csympnet rollout --model`) and predicts the same bits."""
        path = _checks.path("path", path)
        self._m.save(path, json.dumps(self.meta))

    def to_json(self):
        """The model file's text."""
        return self._m.to_json(json.dumps(self.meta))


def load(path):
    """Reads a model file written by the CLI (`run`, `train`, `fit`) or by `Model.save`."""
    path = _checks.path("path", path)
    return Model(_core.load(path))


def from_json(text):
    """A model from the text of a model file (see `Model.to_json`)."""
    if not isinstance(text, str):
        raise TypeError(f"text: expected a str, got {type(text).__name__}")
    return Model(_core.from_json(text))
