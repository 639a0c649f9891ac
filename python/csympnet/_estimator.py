"""csympnet.CSympNetID: CSympNet-ID as a scikit-learn style estimator (PySINDy's conventions).

The estimator runs `csympnet.identify` (what `csympnet fit` runs) and keeps what it found in
attributes ending in an underscore. It follows scikit-learn's rules without importing
scikit-learn: hyperparameters are stored unchanged by __init__ and checked by fit, so that
`sklearn.base.clone`, `GridSearchCV` and `cross_val_score` work; a fitted estimator pickles.
"""

import inspect

import numpy as np

from . import _checks, _records
from ._identify import identify_config, identify_records
from ._records import NoTimesWarning  # noqa: F401 (csympnet.NoTimesWarning, documented here)


class CSympNetID:
    """Identifies a linearly damped Hamiltonian system from its trajectories: the damping rate
    γ with an interval, and an exactly conformally symplectic one-step map
    Φ̂_h = S_a ∘ Ψ_h ∘ S_a, a = exp(−γ̂h/2), in the data's own units.

    Hyperparameters are those of `csympnet.identify` (core, seed, window, loss, normalize,
    epochs, lr, lm_iterations, val_fraction, blocks, level, dof_scales, threads, init: the
    path of a model file to start from), plus
        t_default: the step between samples when fit gets no times (PySINDy's t_default).
            Left at None, fit takes a step of 1 and warns (NoTimesWarning): γ̂ is then per
            sample. score and simulate without times use dt_, the step fitted;
        verbose: progress bars on stderr for each stage (tqdm where it is installed);
        observed: "states" (x holds q and p, or velocities), or "positions" (x holds the
            positions alone, (M, d): the momenta are fitted as hidden states; trajectories
            only). Left at None, an array's columns are read as states with a LayoutWarning
            that names observed="positions"; a pandas DataFrame says which by its column
            names (q1..qd with p1..pd: states; any other names: positions; a t, time or t_ms
            column: the times; a traj column: the trajectories);
        time_unit: the unit of the times ("s", "ms", "us", "ns", "min", "h"), or None (read
            from a DataFrame's time column name such as t_ms, else unknown). Only the report
            changes: gamma_per_s_, report_["time_unit"]; the fit is the same. The fitted model_ still maps states (q, p) in the units it chose for p;
            model_.state_from_positions(q, t) gives the state at the end of a window of
            positions, to predict or roll out from;
        derived_momenta: "set_aside" (default) or "use", as in `csympnet.identify`.
        dissipation: "auto" (default), "viscous", "viscous+coulomb" or "viscous+drag", as in
            `csympnet.identify`.
        record_fit: "auto" (default), "windows" or "whole", as in `csympnet.identify`.

    After fit:
        gamma_           γ̂ in the data's time units, or None when the data do not identify γ
        gamma_interval_  (low, high) at `level`, or None
        time_unit_       the times' unit, or None when unknown
        gamma_per_s_     γ̂ per second when the unit is known and γ identified, else None
        identified_      False when the data do not identify γ or break the model's
                         assumptions (`reasons_` says why)
        verdict_         "identified", "not identified" or "model rejected"
        reasons_         list of str
        checks_          list of dict: the model's assumptions tested (as report_["checks"])
        frequencies_     angular frequencies of the fitted map's modes at its equilibrium
                         (radians per time unit, ascending), or None when not identified
        damping_ratio_   their damping ratios (γ̂ / (2ω) each), or None when not identified;
                         report_["modes"] has both with intervals
        hamiltonian_     the library core's Hamiltonian in the data's units (dict, as
                         `Identification.hamiltonian`), or None when a neural core was chosen
        dissipation_     list of dict, the dissipation found, viscous first (as
                         `Identification.dissipation`: kind, dof, value, low, high, unit)
        model_selection_ list of dict, each decision between models with its runner-up and
                         margin (as `Identification.model_selection`)
        model_           the learned csympnet.Model (predict, rollout, save, ...)
        report_          the full report (dict), as `csympnet fit` writes it
        n_features_in_   2d, the state's length
        dt_              the median step of the data fitted
    """

    def __init__(self, *, core=None, seed=42, window=0, loss="balanced", normalize=True,
                 epochs=0, lr=1e-3, lm_iterations=0, val_fraction=0.2, blocks=20, level=0.95,
                 dof_scales="auto", threads=1, init=None, t_default=None, verbose=False,
                 observed=None, derived_momenta="set_aside", time_unit=None,
                 dissipation="auto", record_fit="auto"):
        self.core = core
        self.seed = seed
        self.window = window
        self.loss = loss
        self.normalize = normalize
        self.epochs = epochs
        self.lr = lr
        self.lm_iterations = lm_iterations
        self.val_fraction = val_fraction
        self.blocks = blocks
        self.level = level
        self.dof_scales = dof_scales
        self.threads = threads
        self.init = init
        self.t_default = t_default
        self.verbose = verbose
        self.observed = observed
        self.derived_momenta = derived_momenta
        self.time_unit = time_unit
        self.dissipation = dissipation
        self.record_fit = record_fit

    # --- scikit-learn's parameter protocol ------------------------------------------------
    @classmethod
    def _param_names(cls):
        sig = inspect.signature(cls.__init__)
        return sorted(p.name for p in sig.parameters.values() if p.name != "self")

    def get_params(self, deep=True):
        """The hyperparameters as a dict (scikit-learn's protocol; `deep` has no effect)."""
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self, **params):
        """Sets hyperparameters by name; returns self. Unknown names raise ValueError."""
        valid = self._param_names()
        for name, value in params.items():
            if name not in valid:
                raise ValueError(
                    f"set_params: unknown hyperparameter {name!r}; expected one of {valid}")
            setattr(self, name, value)
        return self

    def __repr__(self):
        defaults = CSympNetID().get_params()
        changed = {k: v for k, v in self.get_params().items() if v is not defaults[k]
                   and not (isinstance(v, (int, float, str, bool)) and v == defaults[k])}
        return "CSympNetID(" + ", ".join(f"{k}={v!r}" for k, v in changed.items()) + ")"

    # --- fitting ------------------------------------------------------------------------
    def fit(self, x, t=None, *, x_next=None, u=None):
        """Fits to trajectories (PySINDy's order: states first, then times) or to pairs.

        Trajectories:
          - x (M, 2d) with t (M,) sample times, a step, or None (steps of t_default);
          - x (K, M, 2d): K trajectories, with t (M,), (K, M), a step or None;
          - x a list of arrays (M_k, 2d), with t a list of time arrays, a step or None.
        Pairs: x (N, 2d) the states z0, x_next (N, 2d) the states one step later, t the
        steps h, one (N,) or one for all.

        u: known inputs of a driven record, sampled at the times t: (M,) or (M, m) for one
        trajectory x, or a list of such arrays for a list x (identify's u=; the library core
        with the input gain B, report_["input"]).

        Returns self. When the data do not identify γ, this warns (NotIdentifiedWarning),
        sets identified_ = False and gamma_ = None; the model is still fitted.
        """
        data = _records.read_estimator(
            x, t, x_next=x_next, u=u, observed=self.observed, time_unit=self.time_unit,
            t_default=self.t_default, stacklevel=3)
        self.observed_ = data.observed
        config = identify_config(**{name: getattr(self, name) for name in (
            "core", "seed", "window", "loss", "normalize", "epochs", "lr", "lm_iterations",
            "val_fraction", "blocks", "level", "dof_scales", "threads", "init",
            "derived_momenta", "dissipation", "record_fit")})
        result = identify_records(data, config, None, self.verbose, stacklevel=3)
        steps = data.steps()
        self.model_ = result.model
        self.report_ = result.report
        self.time_unit_ = data.time_unit
        self.gamma_per_s_ = self.report_["time_unit"]["gamma_per_s"] if data.time_unit else None
        self.identified_ = result.identified
        self.reasons_ = result.reasons
        self.verdict_ = result.verdict
        self.checks_ = result.checks
        self.gamma_ = result.gamma if result.identified else None
        self.gamma_interval_ = result.interval if result.identified else None
        self.frequencies_ = result.frequencies
        self.damping_ratio_ = result.damping_ratios
        self.hamiltonian_ = result.hamiltonian
        self.dissipation_ = result.dissipation
        self.model_selection_ = result.model_selection
        self.n_features_in_ = 2 * result.model.d
        self.dt_ = float(np.median(steps))
        return self

    def _check_fitted(self):
        if not hasattr(self, "model_"):
            raise RuntimeError("CSympNetID: call fit() first")

    # --- using the fitted map ------------------------------------------------------------
    def predict(self, x, h=None):
        """One step of the learned map: Φ̂_h(x) for a state (2d,) or a batch (N, 2d);
        h a step or one per state (default: dt_, the median step of the data fitted)."""
        self._check_fitted()
        return self.model_.predict(x, self.dt_ if h is None else h)

    def simulate(self, x0, t=None, *, steps=None):
        """The learned map iterated from x0 at the times t (t[0] is x0's time): an array
        (len(t), 2d) whose first row is x0 (PySINDy's simulate). The steps may vary.
        Without t, `steps` steps of dt_ (the step fitted): an array (steps + 1, 2d)."""
        self._check_fitted()
        if t is None:
            if steps is None:
                raise ValueError("simulate: give the times t, or steps= (steps of dt_)")
            n = _checks.integer("steps", steps, minimum=1)
            return self.model_.rollout(x0, self.dt_, steps=n)
        if steps is not None:
            raise ValueError("simulate: give either the times t or steps=, not both")
        times = _checks.vector("t", t)
        if times.shape[0] < 2:
            raise ValueError("t: expected at least two times (x0's and one more)")
        return self.model_.rollout(x0, np.diff(times))

    def score(self, x, t=None, *, x_next=None):
        """R² of one-step predictions over the increments: 1 − Σ‖Φ̂_h(z_n) − z_{n+1}‖² /
        Σ‖Δz_n − mean Δz‖², over every consecutive pair of the trajectories (or the pairs),
        taken as fit takes them, except that without times the step is dt_, the step fitted
        (as in predict). 1 is perfect; predicting no change at all scores about 0. It is `model_.score(...)["one_step_r2"]`; Model.score also gives rollout errors."""
        self._check_fitted()
        data = _records.read_estimator_score(
            x, t, x_next=x_next, step=self.dt_, dim=self.n_features_in_,
            fitted_on_positions=getattr(self, "observed_", "states") == "positions")
        return float(self.model_._score(data)["one_step_r2"])
