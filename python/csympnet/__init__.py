"""csympnet: learn conformally symplectic one-step maps of damped Hamiltonian systems.

CSympNet-ID learns Φ̂_h = S_a ∘ Ψ_h ∘ S_a, a = exp(−γ̂h/2), from snapshot pairs: a symplectic
SympNet core Ψ_h between two momentum scalings, so that DΦ̂ᵀ J DΦ̂ = exp(−γ̂h) J exactly and
the damping rate γ̂ is identified explicitly. This package is the Python face of the C++
library and CLI: same models, same files, same bits.

Identifying γ on your own data, in any units (what `csympnet fit` runs):

    >>> import numpy as np, csympnet
    >>> est = csympnet.CSympNetID().fit(z, t)              # z (M, 2d), t (M,); PySINDy's order
    >>> est.verdict_, est.gamma_, est.gamma_interval_      # "identified", γ̂, (low, high)
    >>> est.checks_                                        # the model's assumptions, tested
    >>> result = csympnet.identify(z, t)                    # the same, as a function
    >>> result.gamma, result.interval, result.verdict

γ̂ comes with an interval only when identified. When the data break the model (energy
gain, damping that depends on amplitude or differs between modes, structured residuals) the
verdict is "model rejected" and a ModelRejectedWarning says which assumption fails.

Training a map, as the paper does (γ̂ is then a training outcome, with no interval):

    >>> data = csympnet.generate("s1", "train")             # the paper's S1 pairs
    >>> model = csympnet.fit(*data, epochs=2000)            # CSympNet-ID, classic recipe
    >>> model.rollout([0.5, -0.2], 0.2, steps=50)           # (51, 2)
    >>> model.save("model.json")                            # `csympnet evaluate --model ...`

Main entry points: CSympNetID and identify (γ on your own data); fit, fit_trajectories
(training a map); run (the paper's presets); load, Model, generate, systems, System,
read_csv, write_csv; figures in csympnet.plot (NumPy + matplotlib only); the same maps as PyTorch
modules that read and write model files in csympnet.torch (imported only on request; needs
torch). See docs/python.md.
"""

from . import _core
from ._core import Error
from ._data import System, generate, model_types, read_csv, systems, write_csv
from ._estimator import CSympNetID
from ._fit import RunResult, fit, fit_trajectories, run
from ._identify import Identification, ModelRejectedWarning, NotIdentifiedWarning, identify
from ._model import Model, from_json, load
from ._records import LayoutWarning, NoTimesWarning, Pairs, Trajectory

__version__ = _core.__version__

Error.__doc__ = """Raised by the C++ library for bad input, bad options or bad files (a
ValueError). The message names the argument, file or line and what was expected."""
Error.__module__ = "csympnet"

__all__ = [
    "CSympNetID", "Error", "Identification", "LayoutWarning", "Model", "ModelRejectedWarning",
    "NoTimesWarning",
    "NotIdentifiedWarning", "Pairs", "RunResult", "System",
    "Trajectory", "fit", "fit_trajectories", "from_json", "generate", "identify", "load",
    "model_types", "read_csv", "run", "systems", "write_csv",
]
