"""Training from Python: csympnet.fit, csympnet.fit_trajectories and csympnet.run."""

import json
import re
import warnings
from collections import namedtuple

import numpy as np

from . import _checks, _core, _records
from ._data import REFERENCES, _system_overrides, systems
from ._model import Model
from ._records import Trajectory
from ._verbose import progress_callback

# The models fit_pairs() trains (paper/fit.hpp); csympnet.run trains every model type.
FIT_MODELS = tuple(_core.fit_models())
# The library's spellings (train/trainer.hpp), in the order Python's messages have named them:
# ("cosine", "constant").
LR_SCHEDULES = tuple(sorted(_core.lr_schedules(), reverse=True))
# The choices of refine= ("auto", then the methods) and run's recipe= (paper/run.hpp).
REFINE_CHOICES = tuple(_core.refine_choices())
RUN_RECIPES = tuple(_core.run_recipes())

RunResult = namedtuple("RunResult", "model report rollouts tests")
RunResult.__doc__ = """What `csympnet.run` returns: the trained Model, the report dict (as
report.json of `csympnet run`), the learned rollouts (list of (n+1, 2d)) and the reference test
trajectories (list of Trajectory) they follow."""


def _core_spec(core):
    """None, a dict, or the CLI's "la:LAYERS:SUBLAYERS[:h2]" / "g:LAYERS:WIDTH" / "library"
    → JSON text."""
    if core is None:
        return "null"
    if isinstance(core, dict):
        return json.dumps(core)
    if core == "library":
        return json.dumps({"type": "library"})
    if isinstance(core, str):
        m = re.fullmatch(r"(la|g):(\d+):(\d+)(:h2)?", core)
        if (not m or int(m.group(2)) < 1 or int(m.group(3)) < 1
                or (m.group(4) and m.group(1) != "la")):
            raise ValueError(
                f"core: expected 'la:LAYERS:SUBLAYERS' (with ':h2' appended for step "
                f"polynomials), 'g:LAYERS:WIDTH' with sizes >= 1 (e.g. 'la:5:20', "
                f"'la:5:20:h2'), 'library', or a dict, got {core!r}"
            )
        kind, a, b = m.group(1), int(m.group(2)), int(m.group(3))
        key = "sublayers" if kind == "la" else "width"
        spec = {"type": kind, "layers": a, key: b}
        if m.group(4):
            spec["step_terms"] = 2
        return json.dumps(spec)
    raise TypeError(
        f"core: expected None, a string like 'la:5:20' or a dict, got {type(core).__name__}")


def _progress(progress):
    if progress is not None and not callable(progress):
        raise TypeError("progress: expected a callable taking a dict, or None")
    return progress


def _warn_if_diverged(model):
    if model.training and model.training.get("stop_reason") == "diverged":
        t = model.training
        warnings.warn(
            f"training diverged at epoch {t.get('epochs_run', 0) + 1} (non-finite loss or "
            f"gradient); the model holds the best checkpoint, from epoch {t.get('best_epoch')}",
            RuntimeWarning, stacklevel=3,
        )


def fit(z0, z1, h, model="csympnet", *, validation=None, epochs=None, core=None, seed=42,
        val_fraction=0.2, beta_init=0.1, beta_decay=True, lr=1e-3, lr_schedule="cosine",
        lr_final_fraction=1e-3, weight_decay=5e-4, val_every=10, warm_start=True,
        refine="auto", refine_iterations=None, refine_solver=None, bootstrap=None, threads=1,
        chunk_pairs=None, batch_size=None, progress=None, verbose=False, meta=None, _groups=None):
    """Trains a one-step map z1 ≈ Φ̂_h(z0) on snapshot pairs with the classic recipe: what
    `csympnet fit --recipe classic` does, with the same defaults, so the same pairs and options
    give the same parameters to the bit. The map's `gamma` is a training outcome, with no
    interval (`gamma_interval` is None). To identify γ on your own data (any units, an
    interval, checks of the model's assumptions, a verdict) use `csympnet.identify` or
    `csympnet.CSympNetID`.

    z0, z1: states (N, 2d), N ≥ 2, rows (q1..qd, p1..pd); h: steps (N,) or one step for all.
    model: "csympnet" (CSympNet-ID, identifies γ̂) or "sympnet" (symplectic, no damping).
    validation: (z0, z1, h) held out for checkpointing; default: a seeded split of the pairs
        with round(val_fraction·N) ≥ 1 validation pairs.
    epochs: budget of full-batch AdamW steps (default: 50,000 for d ≤ 20, 3,000 beyond).
    core: symplectic core, "la:LAYERS:SUBLAYERS", "g:LAYERS:WIDTH" or a dict; default by d
        (LA(5, 20) for d = 1, LA(4, 10) up to d = 20, LA(4, 4) beyond).
    seed: seed of the validation split and the initialisation.
    beta_init: initial β (γ̂ = |β|), nonzero. beta_decay: apply weight decay to β too.
    lr, lr_schedule ("cosine" or "constant"), lr_final_fraction, weight_decay, val_every:
        the optimiser (docs/training.md).
    The defaults are the identification recipe (docs/identification.md), the library's
    FitConfig::identification() (tests/test_fit.py keeps them equal); for the paper's
    recipe pass warm_start=False, refine="none", bootstrap=0.
    warm_start: start β at the closed-form estimate of γ from the data (csympnet only).
    refine: second stage after AdamW: "none" (the paper's recipe), "lm"
        (Levenberg–Marquardt), "lbfgs", or "auto" (default: lm, with the BLAS solver above
        1000 parameters, or lbfgs for large models);
        refine_iterations (default 300), refine_solver ("dense_qr" or
        "dense_normal_cholesky", both Ceres, or "blas_normal_cholesky", the normal
        equations formed once per Jacobian with BLAS: the fastest for thousands of
        parameters; only with refine="lm": "auto" picks it) tune it.
    bootstrap: replicates of a bootstrap of γ̂ over refits on resampled pairs (from
        `fit_trajectories`: whole trajectories), at least 10, or 0/None (default: none). Its
        spread is in `model.meta["bootstrap"]`; it is not an interval for γ (it has not
        passed the identification's checks, and with few trajectories it collapses).
    Add core="la:5:20:h2" when the steps vary (docs/identification.md).
    threads: threads for each training epoch of CSympNet-ID with d > 1 (other models train
        on one); the results are the same to the bit for any value.
    chunk_pairs: pairs per chunk of the loss's sums (default None: one chunk up to 512 training
        pairs, 256 above); the chunks' sums follow one fixed tree, so the result depends on
        the chunk size, never on threads (docs/training.md, "Large data sets").
    batch_size: mini-batches of this many pairs, reshuffled each epoch (default None: one
        full-batch step per epoch); epochs still count passes over the data.
    progress: optional callable, called after each AdamW validation and each accepted step
        of the second stage with a dict: stage ("adamw", "lm" or "lbfgs"), epoch and epochs
        (iterations and budget for lm and lbfgs), train_loss (None where the optimiser does not
        say), val_loss, best_val_loss, gamma, seconds (of that stage); returning False ends the
        fit, keeping the best parameters so far.
    verbose: True draws a progress bar per stage on stderr (AdamW, LM or L-BFGS, the
        bootstrap), with tqdm where it is installed; with `progress` too, both run.
    meta: dict merged into the model's `meta` (saved with it), e.g. {"system": {...}}.

    Returns a Model holding the best-validation parameters; its `gamma` is γ̂ as trained
    (`meta["gamma_interval_note"]` says where to get an interval; `meta["warnings"]` holds a
    warning about the data's scale, which is also issued as a UserWarning). Training runs
    without the GIL; Ctrl-C stops it with KeyboardInterrupt.
    """
    _checks.choice("model", model, FIT_MODELS)
    a0, a1, hs = _records.pairs("", z0, z1, h, train=True)
    if a0.shape[0] < 2 and validation is None:
        raise ValueError(
            f"z0: {a0.shape[0]} pair(s); expected at least 2 (one is held out for validation), "
            "or pass validation="
        )
    val = None
    if validation is not None:
        if not isinstance(validation, (tuple, list)) or len(validation) != 3:
            raise TypeError("validation: expected a (z0, z1, h) triple")
        val = _records.pairs("validation ", *validation, train=True)
        if val[0].shape[1] != a0.shape[1]:
            raise ValueError(
                f"validation z0: states have {val[0].shape[1]} components, expected "
                f"{a0.shape[1]} (as the training pairs)"
            )
    # Only the kinds of the arguments are checked here; their ranges and the rules between them
    # (refine_solver needs refine="lm", ...) are the library's (make_fit_config), which
    # refuses a value with a csympnet.Error naming the argument.
    # None (epochs, bootstrap, refine_iterations, refine_solver): the library chooses.
    if epochs is not None:
        epochs = _checks.integer("epochs", epochs)
    seed = _checks.seed("seed", seed)
    val_fraction = _checks.real("val_fraction", val_fraction)
    beta_init = _checks.real("beta_init", beta_init)
    if not isinstance(beta_decay, (bool, np.bool_)):
        raise TypeError(f"beta_decay: expected True or False, got {type(beta_decay).__name__}")
    lr = _checks.real("lr", lr)
    _checks.choice("lr_schedule", lr_schedule, LR_SCHEDULES)
    lr_final_fraction = _checks.real("lr_final_fraction", lr_final_fraction)
    weight_decay = _checks.real("weight_decay", weight_decay)
    val_every = _checks.integer("val_every", val_every)
    if not isinstance(warm_start, (bool, np.bool_)):
        raise TypeError(f"warm_start: expected True or False, got {type(warm_start).__name__}")
    # The spellings are the library's (paper/fit.hpp); "auto" leaves the choice to it.
    _checks.choice("refine", refine, REFINE_CHOICES)
    if refine_iterations is not None:
        refine_iterations = _checks.integer("refine_iterations", refine_iterations)
    if refine_solver is not None:
        _checks.choice("refine_solver", refine_solver, tuple(_core.linear_solvers()))
    if bootstrap is not None:
        bootstrap = _checks.integer("bootstrap", bootstrap)
    threads = _checks.integer("threads", threads, maximum=2**31 - 1)  # a C++ int
    if chunk_pairs is not None:
        chunk_pairs = _checks.integer("chunk_pairs", chunk_pairs)
    if batch_size is not None:
        batch_size = _checks.integer("batch_size", batch_size)
    groups = [] if _groups is None else [int(g) for g in _groups]
    if meta is not None and not isinstance(meta, dict):
        raise TypeError(f"meta: expected a dict, got {type(meta).__name__}")

    with progress_callback(progress, verbose) as callback:
        m = Model(_core.fit_pairs(a0, a1, hs, val, model, _core_spec(core), seed, val_fraction,
                                  beta_init, epochs, val_every, lr, lr_schedule,
                                  lr_final_fraction, weight_decay, bool(beta_decay),
                                  bool(warm_start), refine, refine_iterations, refine_solver,
                                  bootstrap, groups, threads, chunk_pairs, batch_size,
                                  callback))
    if meta:
        m.meta.update(meta)
    _warn_if_diverged(m)
    for text in m.meta.get("warnings", []):
        warnings.warn("csympnet.fit: " + text, UserWarning, stacklevel=2)
    return m


def _dims(x):
    """ndim of an array, or of a list's first array (the trajectory forms' lists)."""
    if isinstance(x, (list, tuple)) and len(x) and not np.isscalar(x[0]):
        return np.ndim(x[0])
    return np.ndim(x)


def fit_trajectories(z, t, traj=None, model="csympnet", **options):
    """Fits from whole trajectories: consecutive states of each trajectory become pairs at
    whatever steps they have (h = t[n] − t[n−1]); no pair spans two trajectories. The same
    pairs as `csympnet fit --recipe classic` makes from a trajectories CSV, in the same order.

    States first, then times, as in `identify(z, t)` and `CSympNetID.fit(x, t)`. Accepted forms:
      - z (M, 2d), t (M,): one trajectory;
      - z (M, 2d), t (M,), traj (M,): rows labelled by trajectory (rows of one label contiguous);
      - z (K, M, 2d), t (M,) or (K, M): K trajectories (shared or own times);
      - z and t lists of arrays: one trajectory each.

    The older order (t, z) is recognised, since times always have one dimension fewer than
    states: it is swapped, with a FutureWarning.

    options: those of `csympnet.fit` (epochs, core, seed, validation, ...).
    """
    if _dims(z) < _dims(t):
        warnings.warn("fit_trajectories takes (z, t), states first, as identify and "
                      "CSympNetID.fit do; the arguments given look like (t, z) and were "
                      "swapped. Pass them as (z, t).", FutureWarning, stacklevel=2)
        z, t = t, z
    checked = _records.trajectories(z, t, traj)
    if sum(len(tr.t) - 1 for tr in checked) < 1:
        raise ValueError("t, z: the trajectories give no pairs; expected at least one with 2 rows")
    z0, z1, h = _core.pairs_from_trajectories(checked)
    if "_groups" in options:
        raise TypeError("fit_trajectories: unexpected keyword '_groups'")
    # The trajectory of each pair, so that a bootstrap resamples whole trajectories.
    groups = np.repeat(np.arange(len(checked)), [len(tr.t) - 1 for tr in checked])
    return fit(z0, z1, h, model, _groups=groups, **options)


def run(preset, model="csympnet", *, seed=42, epochs=None, sigma=0.0, recipe="default", lr=None,
        lr_schedule=None, val_every=10, beta_init=0.1, beta_decay=True, reference="splitting",
        system=None, threads=1, progress=None):
    """One experiment as `csympnet run --preset PRESET --model MODEL` runs it: generate the
    preset's data, train, evaluate on the test trajectories (data seed 0). Trains any model
    type (`csympnet.model_types()`), including the baselines.

    epochs: budget (default: the preset's); recipe: "default" (cosine-annealed rate) or
    "paper" (constant rate); sigma: relative observation noise; system: dict of fields that
    replace the preset's system; threads, progress: as in `csympnet.fit`.

    Returns RunResult(model, report, rollouts, tests).
    """
    _checks.choice("preset", preset, tuple(systems))
    _checks.choice("model", model, tuple(_core.model_types()))
    _checks.choice("recipe", recipe, RUN_RECIPES)
    _checks.choice("reference", reference, REFERENCES)
    # The kinds here; the ranges are the library's (RunConfig::validate).
    seed = _checks.seed("seed", seed)
    if epochs is not None:
        epochs = _checks.integer("epochs", epochs)
    sigma = _checks.real("sigma", sigma)
    if lr is not None:
        lr = _checks.real("lr", lr)
    if lr_schedule is not None:
        _checks.choice("lr_schedule", lr_schedule, LR_SCHEDULES)
    val_every = _checks.integer("val_every", val_every)
    beta_init = _checks.real("beta_init", beta_init)
    threads = _checks.integer("threads", threads, maximum=2**31 - 1)  # a C++ int
    core_model, report, rollouts, tests = _core.run(
        preset, model, seed, epochs, recipe, lr, lr_schedule, val_every, sigma, beta_init,
        bool(beta_decay), reference, _system_overrides(system), threads, _progress(progress))
    m = Model(core_model)
    _warn_if_diverged(m)
    return RunResult(m, json.loads(report), list(rollouts), [Trajectory(t, z) for t, z in tests])
