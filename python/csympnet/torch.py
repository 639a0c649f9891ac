"""csympnet.torch: csympnet's one-step maps as PyTorch modules that read and write its model files.

CSympNet-ID (Φ̂_h = S_a ∘ Ψ_h ∘ S_a, a = exp(−γ̂h/2)) over an LA-SympNet or G-SympNet core, the
bare cores and SympNet, and the two wrappers of a `csympnet fit` model (its units,
"normalization", and learned per-dof momentum scales, "dof_scales"), as torch.nn.Modules whose
parameters are nn.Parameters: train them with any torch optimiser, on any device and dtype
(`module.to("cuda")`, `module.double()`). The forward pass follows the parameters' dtype and
device and holds no NumPy.

    >>> import torch, csympnet.torch as ct
    >>> net = ct.CSympNetID(1, core="la:5:20")           # a fresh model, d = 1
    >>> z1 = net(z0, h)                                  # z0 (N, 2d) tensor, h a number or (N,)
    >>> ct.save(net, "model.json")                       # `csympnet fit DATA --init model.json`
    >>> net = ct.load("out/model.json")                  # any csympnet model file of these kinds

A file written by `save` is read by the CLI (`evaluate`, `rollout`, `fit --init`) and by
`csympnet.load`, with θ to the bit; in float64 the module predicts what the C++ predicts to
rounding. See docs/python.md, "Training in PyTorch".
"""

from __future__ import annotations

import json
import os

try:
    import torch
except ImportError as _e:  # torch is optional: csympnet itself needs none
    raise ImportError(
        "csympnet.torch needs PyTorch, which is not installed: install python3-torch "
        "(Debian, Ubuntu) or torch (pip install torch)") from _e

from . import _checks, _core
from ._fit import _core_spec
from ._model import Model
from ._torch_cores import Core, GSympNet, LASympNet
from ._torch_maps import CoreMap, CSympNetIDMap, DofScaledMap, NormalizedMap, OneStepMap, SympNet

__all__ = ["CSympNetID", "Core", "CoreMap", "CSympNetIDMap", "DofScaledMap", "GSympNet",
           "LASympNet", "NormalizedMap", "OneStepMap", "SympNet", "from_spec", "load", "save",
           "to_model"]

# The model types a module can be built for; the vector fields and the MLP map baseline are
# refused by name.
_TYPES = ("csympnet", "sympnet", "la", "g")


def _core_module(spec, d, dtype, device):
    kind = spec["type"]
    if kind == "la":
        return LASympNet(d, spec["layers"], spec["sublayers"], spec.get("step_terms", 1),
                         dtype=dtype, device=device)
    return GSympNet(d, spec["layers"], spec["width"], dtype=dtype, device=device)


def _build(spec, dtype, device):
    if "normalization" in spec:
        inner = _build({k: v for k, v in spec.items() if k != "normalization"}, dtype, device)
        n = spec["normalization"]
        return NormalizedMap(inner, n["q_shift"], n["q_scale"], n["p_scale"], n["time_scale"])
    if "dof_scales" in spec:
        return DofScaledMap(_build({k: v for k, v in spec.items() if k != "dof_scales"}, dtype,
                                   device))
    kind, d = spec["type"], spec["d"]
    if kind not in _TYPES:
        raise ValueError(f"csympnet.torch: model type {kind!r} has no torch module; expected "
                         f"one of {', '.join(_TYPES)} (the vector-field models and the map "
                         "baseline stay in csympnet)")
    if kind in ("la", "g"):
        return CoreMap(_core_module(spec, d, dtype, device))
    core = _core_module(spec["core"], d, dtype, device)
    if kind == "sympnet":
        return SympNet(core)
    return CSympNetIDMap(core, spec.get("beta_init", 0.1))


def from_spec(spec, params=None, *, dtype=torch.float64, device=None):
    """A module for a model file's architecture (`spec`: its "model" entry, a dict) with the flat
    parameters `params` (θ in the file's order; default: zeros, with β = beta_init). The spec is
    checked by the C++ library, with its messages."""
    if not isinstance(spec, dict):
        raise TypeError(f"spec: expected a dict (a model file's \"model\" entry), got "
                        f"{type(spec).__name__}")
    spec_json, n_params = _core.spec_info(json.dumps(spec))
    module = _build(json.loads(spec_json), dtype, device)
    if module.n_params != n_params:  # the layouts of this package and the library disagree
        raise RuntimeError(f"csympnet.torch: {module.n_params} parameters for {spec_json}, "
                           f"the library counts {n_params}")
    if params is not None:
        theta = torch.as_tensor(params, dtype=torch.float64).reshape(-1).cpu()
        if theta.numel() != n_params:
            raise ValueError(f"params: has {theta.numel()} entries, the architecture needs "
                             f"{n_params}")
        module.load_flat(theta)
    return module


def CSympNetID(d, core="la:5:20", *, beta_init=0.1, dof_scales=False, normalization=None,
               seed=0, dtype=torch.float64, device=None):
    """A fresh CSympNet-ID module for d degrees of freedom, to train in torch.

    core: the CLI's "la:LAYERS:SUBLAYERS[:h2]" or "g:LAYERS:WIDTH", or a core dict of the model
        file ({"type": "la", "layers": 5, "sublayers": 20}).
    beta_init: β at the start (γ̂ = |β|), nonzero.
    dof_scales: True learns per-dof momentum scales (data with velocities, d > 1).
    normalization: None (the map works in the data's units), or a dict with q_shift, q_scale,
        p_scale (d each, q_scale[i] * p_scale[i] the same for all i) and time_scale: the map
        then works in the user's units around a core in normalised ones.
    seed: the core's matrices and amplitudes are drawn N(0, 0.01²) from torch.Generator(seed);
        biases and step coefficients start at 0 (csympnet's scheme, not its draws).
    """
    spec = {"type": "csympnet", "d": d, "core": json.loads(_core_spec(core)),
            "beta_init": beta_init}
    if dof_scales:
        spec["dof_scales"] = "learned"
    if normalization is not None:
        spec["normalization"] = dict(normalization)
    module = from_spec(spec, dtype=dtype, device=device)
    generator = torch.Generator().manual_seed(int(seed))
    _core_of(module).init_random(generator)
    return module


def _core_of(module):
    while not isinstance(module, (CSympNetIDMap, CoreMap)):
        module = module.inner
    return module.core


def to_model(module, meta=None):
    """The csympnet.Model (the C++ model) with the module's architecture and θ."""
    if not isinstance(module, OneStepMap):
        raise TypeError(f"module: expected a csympnet.torch module, got {type(module).__name__}")
    meta = {} if meta is None else meta
    if not isinstance(meta, dict):
        raise TypeError(f"meta: expected a dict, got {type(meta).__name__}")
    theta = module.flat_params().numpy()
    return Model(_core.from_spec(json.dumps(module.spec()), theta, json.dumps(meta)))


def save(module, path, *, meta=None, overwrite=False):
    """Writes the module as a csympnet model file (versioned, checksummed JSON, θ to the bit;
    atomically). An existing file is kept unless overwrite=True (FileExistsError). `meta`: a dict
    saved with it (default: the `meta` of a loaded module, plus its source)."""
    path = _checks.path("path", path)
    if meta is None:
        meta = dict(getattr(module, "meta", {}))
        meta["source"] = "csympnet.torch"
    model = to_model(module, meta)
    if not overwrite and os.path.lexists(path):
        raise FileExistsError(f"{path}: exists; pass overwrite=True to replace it")
    model.save(path)


def load(path, *, dtype=torch.float64, device=None):
    """A module from a csympnet model file (checksum checked): CSympNet-ID, SympNet or a bare
    core, with the wrappers of a `csympnet fit` model. The file's meta is kept as `module.meta`.
    """
    path = _checks.path("path", path)
    model = Model(_core.load(path))
    if model.type not in _TYPES:
        raise ValueError(f"{path}: model type {model.type!r} has no torch module; expected one "
                         f"of {', '.join(_TYPES)}")
    module = from_spec(model.hyperparams, model.params, dtype=dtype, device=device)
    module.meta = model.meta
    return module
