"""Identification on one's own data: what `csympnet fit` runs (docs/identification.md)."""

import json
import os
import warnings

import numpy as np

from . import _checks, _core, _records
from ._fit import _core_spec
from ._model import Model
from ._verbose import progress_callback

# The library's spellings (identify/identify.hpp).
LOSSES = tuple(_core.identify_losses())
DOF_SCALES = tuple(_core.dof_scales())


class NotIdentifiedWarning(UserWarning):
    """The data do not identify γ; `Identification.reasons` says why."""


def time_unit_report(report, time_unit, source):
    """The report's "time_unit" object (identify/time_unit.hpp), added in place."""
    report["time_unit"] = json.loads(_core.time_unit_report(time_unit, source, json.dumps(report)))
    return report


class ModelRejectedWarning(NotIdentifiedWarning):
    """The data break an assumption of the model (energy gain, damping that depends on the
    amplitude or differs between modes, structured residuals); `Identification.checks` and
    `reasons` say which, and what the data show instead. A NotIdentifiedWarning too."""


class Identification:
    """The result of `identify`: the model (in the data's own units), γ̂, its interval and
    the verdict.

    Attributes:
      model       Model (exactly conformally symplectic in the data's units)
      gamma       γ̂ in the data's time units; None unless identified (as CSympNetID.gamma_)
      interval    (low, high); None unless identified
      level       the interval's level
      identified  False when the data do not identify γ or break the model's assumptions
                  (then `reasons` says why)
      verdict     "identified", "not identified" or "model rejected"
      reasons     list of str: failed checks first
      checks      list of dict: each assumption tested, with its statistic, p-value,
                  effect size, threshold, passed, and a sentence in words
      modes       list of dict, one per oscillating mode of the fitted map linearised at its
                  equilibrium (ascending frequency): angular_frequency (radians per time
                  unit), damping_ratio, and their intervals (None unless identified); for a
                  nonlinear system, small oscillations about the equilibrium
      frequencies the modes' angular frequencies (numpy array); None unless identified
      damping_ratios  the modes' damping ratios (numpy array, γ̂ / (2ω)); None unless
                  identified
      time_unit   the clock's unit ("s", "ms", "us", "ns", "min", "h"), given as time_unit=
                  or read from a DataFrame's time column name (t_ms, ...); None when unknown
      gamma_per_s γ̂ per second when the unit is known (only the report changes with it, never
                  the fit); None otherwise or unless identified
      amplitude_decay_rate  γ̂/2, the rate at which amplitudes decay (e^{−γt/2}), in the
                  data's time units; None unless identified
      hamiltonian the library core's Hamiltonian in the data's units (dict: "potential" as
                  text, "terms" with coefficient, interval and, for sin/cos/exp, wavenumber,
                  "inverse_mass", "mass"); None when an LA or G core was chosen
      dissipation list of dict, the dissipation found, viscous first: {"kind": "viscous" |
                  "coulomb" | "drag", "dof" (1-based, None for γ), "value", "low", "high"
                  (None unless identified), "unit"}; Coulomb friction as the deceleration μ
                  of its coordinate (q'' = ... − μ sign(q')), drag as c (q'' = ... − c q'|q'|)
      dissipation_sentence  the same in words: "viscous gamma = … plus dry friction mu = …"
      model_selection  list of dict, one per decision between models: "decision", "chosen",
                  "runner_up", "criterion", the losses it used ("chosen_value",
                  "runner_up_value") and "margin" in "margin_unit" (BIC, standard errors or
                  relative): how close each call was
      estimate    the fitted γ̂ whatever the verdict (for inspection, not a measurement)
      report      the full report (dict), the same as `csympnet fit` writes
    """

    def __init__(self, model, report):
        self.model = model
        self.report = report
        self.identified = bool(report["identified"])
        self.verdict = report["verdict"]
        self.estimate = report["gamma_hat"]
        self.gamma = report["gamma_hat"] if self.identified else None
        low, high = report["gamma_ci_low"], report["gamma_ci_high"]
        self.interval = None if low is None or not self.identified else (low, high)
        self.level = report["gamma_ci_level"]
        self.reasons = list(report["reasons"])
        self.checks = list(report["checks"])
        self.modes = list(report["modes"]["list"])
        self.frequencies = (np.array([m["angular_frequency"] for m in self.modes])
                            if self.identified else None)
        self.damping_ratios = (np.array([m["damping_ratio"] for m in self.modes])
                               if self.identified else None)
        self.hamiltonian = report.get("hamiltonian")
        dissipation = report.get("dissipation") or {}
        self.dissipation = list(dissipation.get("terms", []))
        self.dissipation_sentence = dissipation.get("sentence")
        self.model_selection = list(report.get("model_selection") or [])
        unit = report.get("time_unit")
        self.time_unit = unit["unit"] if unit else None
        self.gamma_per_s = unit["gamma_per_s"] if unit else None
        self.amplitude_decay_rate = self.gamma / 2.0 if self.identified else None

    def __repr__(self):
        if not self.identified:
            return f"Identification({self.verdict}: {'; '.join(self.reasons) or 'interrupted'})"
        low, high = self.interval
        per = f" per {self.time_unit}" if self.time_unit else ""
        return (f"Identification(gamma={self.gamma:.6g}{per}, {100 * self.level:g}% interval "
                f"[{low:.6g}, {high:.6g}])")


def identify(z=None, t=None, traj=None, *, pairs=None, core=None, seed=42, window=0,
             loss="balanced", normalize=True, epochs=0, lr=1e-3, lm_iterations=0,
             val_fraction=0.2, blocks=20, level=0.95, dof_scales="auto", threads=1,
             init=None, progress=None, verbose=False, observed=None,
             derived_momenta="set_aside", time_unit=None, dissipation="auto", u=None,
             record_fit="auto"):
    """Identifies γ from trajectories (or pairs) in any units: `csympnet fit` from Python.

    Arguments follow PySINDy's order, states first: `identify(z, t)` for one trajectory
    (z (M, 2d), t (M,)), `identify(z, t, traj)` for rows labelled by trajectory, or lists of
    arrays, or z (K, M, 2d); `identify(pairs=(z0, z1, h))` for independent pairs.

    z may be a pandas DataFrame (or Series), read by column name (pandas is not imported
    unless you give one): a time column t, time or with a unit (t_ms, time_s, "t [s]"), a
    traj column, and q1..qd with p1..pd (states) or any other names (positions alone).

    observed: "states" (z holds q and p, or velocities) or "positions". Not given, an array's
    columns are read as states, q1..qd then p1..pd, with a LayoutWarning naming
    observed="positions" (two position columns would otherwise be one coordinate and its
    momentum); a DataFrame's layout comes from its column names.

    time_unit: the unit of t ("s", "ms", "us", "ns", "min", "h"), or None (then read from a
    DataFrame's time column name, else unknown). It changes only the report: report
    ["time_unit"] gives γ̂ and its interval per second and the amplitude decay rate γ̂/2.

    observed="positions": z holds positions alone, (M, d) (or (M,) for d = 1, lists, or
    (K, M, d)), as a camera or an encoder records them. The momenta are then hidden states
    fitted with the map and the loss is on the positions (report["observed"] is "positions";
    docs/identification.md, "Positions only"). Momenta given with the positions that are a
    filter of them (numpy.gradient, Savitzky-Golay) are recognised and set aside the same way;
    derived_momenta="use" keeps them (with a warning in the measured_momenta check: the
    interval does not cover the filter's bias).

    The data are normalised (q shift, per-dof scales that keep the structure, time scale),
    whole trajectories or segments of a long one are held out, windows of `window` steps
    (0: automatic) are fitted with balanced residuals (`loss="one-step"` for the paper's),
    then Levenberg–Marquardt. Without `core`, the Hamiltonian-library core is fitted first
    (`result.hamiltonian` then gives its terms in the data's units); unless it explains the
    held-out data to the noise floor, an LA and a G core are trained too and the lowest
    validation loss wins (`report["choices"]["core_candidates"]`; `core="library"` forces
    the library core). With d > 1 the
    momenta's per-dof scales are learned too (`dof_scales`), so velocities work as well as
    momenta. The interval is a cluster-robust sandwich over blocks, widened by the held-out
    over training loss when that exceeds 1. When the data do not identify γ this warns
    (NotIdentifiedWarning) and returns identified=False.
    Ctrl-C raises KeyboardInterrupt within about a second.

    dissipation: "auto" (default: with the library core, Coulomb friction or quadratic drag
    on every coordinate enter beside γ when the held-out loss and the amplitude check both
    call for them), "viscous" (γ alone), "viscous+coulomb" or "viscous+drag" (that term
    fitted as given, the library core the only candidate). `result.dissipation` lists what
    was found with intervals; the same as `csympnet fit --dissipation`.

    record_fit: how trajectories with momenta are fitted: "auto" (default), "windows" (the
    balanced windows of a few steps) or "whole" (then the whole record by multiple shooting,
    q and p observed each with its own noise, and its interval); the same as
    `csympnet fit --record-fit`.

    init: the path of a CSympNet-ID model file to start from (`csympnet fit --init`; written by
    `fit`, `Model.save` or `csympnet.torch.save`): its core, parameters and units are kept (the
    data are normalised with the file's normalisation, or fitted in their own units when it has
    none), AdamW runs only when `epochs` is given, and LM refines. `core` cannot be given with
    it. The report records the file and its checksum under "init".

    progress: optional callable, called after each AdamW validation and each accepted LM step
    with a dict (stage "adamw" or "lm", epoch, epochs, train_loss, val_loss, best_val_loss,
    gamma, seconds); returning False ends that stage with its best parameters.
    verbose: True draws a progress bar per stage on stderr (tqdm where it is installed).

    u: known inputs of a driven record, sampled at the times t: (M,) or (M, m) for one
    trajectory, or a list of such arrays, one per trajectory of a list z (no traj labels, no
    pairs). The driven model H = H0 - q^T B u(t) is then fitted with the library core on the
    positions (momenta given are set aside), and report["input"] holds B, the gain on the
    acceleration (q'' = ... + B u), with its interval (docs/identification.md, "Driven
    records"); `csympnet fit` on a file with columns u1..um runs the same path.

    Returns an Identification.
    """
    data = _records.read(z, t, traj, pairs_given=pairs, observed=observed, u=u,
                         time_unit=time_unit, stacklevel=3)
    config = identify_config(
        core=core, seed=seed, window=window, loss=loss, normalize=normalize, epochs=epochs,
        lr=lr, lm_iterations=lm_iterations, val_fraction=val_fraction, blocks=blocks,
        level=level, dof_scales=dof_scales, threads=threads, init=init,
        derived_momenta=derived_momenta, dissipation=dissipation, record_fit=record_fit)
    return identify_records(data, config, progress, verbose, stacklevel=3)


def identify_config(*, core, seed, window, loss, normalize, epochs, lr, lm_iterations,
                    val_fraction, blocks, level, dof_scales, threads, init, derived_momenta,
                    dissipation, record_fit):
    """identify's options as the library's config (JSON text). Only their kinds are checked
    here; the ranges are the library's (make_identify_config), which refuses a value with a
    csympnet.Error naming the argument."""
    _checks.choice("loss", loss, LOSSES)
    _checks.choice("dof_scales", dof_scales, DOF_SCALES)
    if not isinstance(normalize, (bool, np.bool_)):
        raise TypeError(f"normalize: expected True or False, got {type(normalize).__name__}")
    config = {
        "seed": _checks.seed("seed", seed),
        "window": _checks.integer("window", window),
        "balanced": loss == "balanced",
        "normalize": bool(normalize),
        "epochs": _checks.integer("epochs", epochs),
        "lr": _checks.real("lr", lr),
        "lm_iterations": _checks.integer("lm_iterations", lm_iterations),
        "val_fraction": _checks.real("val_fraction", val_fraction),
        "blocks": _checks.integer("blocks", blocks),
        "level": _checks.real("level", level),
        "threads": _checks.integer("threads", threads, maximum=2**31 - 1),  # a C++ int
        "dof_scales": dof_scales,
        "derived_momenta": derived_momenta,
        "dissipation": dissipation,
        "record_fit": record_fit,
    }
    if core is not None:
        config["core"] = json.loads(_core_spec(core))
    if init is not None:
        if not isinstance(init, (str, os.PathLike)):
            raise TypeError(f"init: expected the path of a model file, got {type(init).__name__}")
        config["init"] = _checks.path("init", init)
    return json.dumps(config)


def identify_records(data, config, progress, verbose, stacklevel=2):
    """Runs the library's identification on records read by _records.py with a config from
    identify_config: an Identification, with a NotIdentifiedWarning (or ModelRejectedWarning)
    when γ is not identified. `stacklevel` is that of a warning issued in this function."""
    with progress_callback(progress, verbose) as callback:
        core_model, report_text = _core.identify(data.trajectories, data.pairs, config, callback,
                                                 data.positions_only, data.inputs)
    report = time_unit_report(json.loads(report_text), data.time_unit, data.unit_source)
    result = Identification(Model(core_model), report)
    if not result.identified:
        rejected = result.verdict == "model rejected"
        warnings.warn(f"csympnet.identify: {result.verdict}: " + "; ".join(result.reasons),
                      ModelRejectedWarning if rejected else NotIdentifiedWarning,
                      stacklevel=stacklevel)
    return result
