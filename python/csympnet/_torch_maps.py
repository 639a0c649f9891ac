"""The one-step maps of csympnet's model files as torch.nn.Modules: CSympNet-ID and SympNet over
a core, and the two wrappers of a `csympnet fit` model (src/models/csympnet_id.hpp,
include/csympnet/models/{dof_scaled_map,normalized_map}.hpp)."""

from __future__ import annotations

import torch
from torch import nn

from ._torch_cores import Core


def _steps(h, z):
    """h (a number, a 0-d or (N,) tensor) as an (N, 1) column of z's dtype and device."""
    h = torch.as_tensor(h, dtype=z.dtype, device=z.device)
    if h.dim() == 0:
        return h.expand(z.shape[0]).unsqueeze(1)
    if h.shape != (z.shape[0],):
        raise ValueError(f"h: expected a number or a tensor of shape ({z.shape[0]},), "
                         f"got shape {tuple(h.shape)}")
    return h.unsqueeze(1)


class OneStepMap(nn.Module):
    """A one-step map z ↦ Φ_h(z). `module(z, h)`: z of shape (N, 2d) (rows are states, q then p)
    or (2d,), h a number or one step per state (N,); returns the next states, shaped as z.

    Every map has `d`, `n_params`, `gamma` (a tensor, or None for a map without damping),
    `spec()` (the "model" entry of its model file) and `flat_params()` (θ in the file's order).
    """

    d: int

    def forward(self, z, h):
        single = z.dim() == 1
        if single:
            z = z.unsqueeze(0)
        if z.dim() != 2 or z.shape[1] != 2 * self.d:
            raise ValueError(f"z: expected shape (N, {2 * self.d}) or ({2 * self.d},), "
                             f"got {tuple(z.shape)}")
        out = self.step(z, _steps(h, z))
        return out[0] if single else out

    def step(self, z, h):  # pragma: no cover - every map defines it
        raise NotImplementedError

    @property
    def gamma(self):
        return None

    @property
    def n_params(self):
        return sum(t.numel() for t in self.blocks())

    def flat_params(self):
        """θ as csympnet's model file holds it: a float64 CPU tensor, detached."""
        blocks = [b.detach().to(device="cpu", dtype=torch.float64).reshape(-1)
                  for b in self.blocks()]
        return torch.cat(blocks) if blocks else torch.zeros(0, dtype=torch.float64)


class CoreMap(OneStepMap):
    """A bare core as a map (model types "la" and "g")."""

    def __init__(self, core: Core):
        super().__init__()
        self.d, self.core = core.d, core

    def spec(self):
        return {**self.core.spec(), "d": self.d}

    def blocks(self):
        return self.core.blocks()

    def load_flat(self, theta):
        return self.core.load_flat(theta)

    def step(self, z, h):
        return self.core(z, h)


class SympNet(CoreMap):
    """SympNet (model type "sympnet"): the symplectic core alone, Φ_h = Ψ_h."""

    def spec(self):
        return {"type": "sympnet", "d": self.d, "core": self.core.spec()}


class CSympNetIDMap(OneStepMap):
    """CSympNet-ID: Φ̂_h = S_a ∘ Ψ_h ∘ S_a, S_a(q, p) = (q, a p), a = exp(−γ̂ h / 2), γ̂ = |β|.
    DΦ̂ᵀ J DΦ̂ = exp(−γ̂ h) J for every θ, z and h. θ: the core's, then β."""

    def __init__(self, core: Core, beta_init=0.1):
        super().__init__()
        beta_init = float(beta_init)
        if beta_init == 0.0 or beta_init != beta_init or abs(beta_init) == float("inf"):
            raise ValueError(f"beta_init: expected a finite nonzero number, got {beta_init!r} "
                             "(d|beta|/dbeta vanishes at 0, so beta would never train)")
        self.d, self.core, self.beta_init = core.d, core, beta_init
        p = next(core.parameters())
        self.beta = nn.Parameter(torch.tensor(beta_init, dtype=p.dtype, device=p.device))

    def spec(self):
        return {"type": "csympnet", "d": self.d, "core": self.core.spec(),
                "beta_init": self.beta_init}

    def blocks(self):
        return self.core.blocks() + [self.beta.reshape(1)]

    @torch.no_grad()
    def load_flat(self, theta):
        off = self.core.load_flat(theta)
        self.beta.copy_(theta[off])
        return off + 1

    @property
    def gamma(self):
        return torch.abs(self.beta)

    def step(self, z, h):
        d = self.d
        a = torch.exp(-0.5 * torch.abs(self.beta) * h)
        q, p = self.core.flow(z[:, :d], a * z[:, d:], h)
        return torch.cat([q, a * p], dim=1)


class DofScaledMap(OneStepMap):
    """Learned per-dof momentum scales (spec key "dof_scales": "learned"): Φ(z) = D⁻¹ Φ̂(D z),
    D = diag(1 on q, μ on p), μ_1 = 1, μ_i = exp(ν_i). θ: the wrapped map's, then ν (d − 1)."""

    def __init__(self, inner: OneStepMap):
        super().__init__()
        self.d, self.inner = inner.d, inner
        p = next(inner.parameters())
        self.log_scales = nn.Parameter(torch.zeros(inner.d - 1, dtype=p.dtype, device=p.device))

    def spec(self):
        return {**self.inner.spec(), "dof_scales": "learned"}

    def blocks(self):
        return self.inner.blocks() + [self.log_scales]

    @torch.no_grad()
    def load_flat(self, theta):
        off = self.inner.load_flat(theta)
        self.log_scales.copy_(theta[off:off + self.d - 1])
        return off + self.d - 1

    def scales(self):
        """μ (d,), μ_1 = 1."""
        one = torch.ones(1, dtype=self.log_scales.dtype, device=self.log_scales.device)
        return torch.cat([one, torch.exp(self.log_scales)])

    @property
    def gamma(self):
        return self.inner.gamma

    def step(self, z, h):
        d, mu = self.d, self.scales()
        out = self.inner.step(torch.cat([z[:, :d], mu * z[:, d:]], dim=1), h)
        return torch.cat([out[:, :d], (1.0 / mu) * out[:, d:]], dim=1)


class NormalizedMap(OneStepMap):
    """A map in the user's units (spec key "normalization"): Φ(z, h) = N⁻¹ Φ̂(N z, h / τ) with
    N z = ((q − s) / α, p / β), α_i β_i equal for all i; γ = γ̂ / τ. The normalisation is held
    in buffers (it moves with `.to()`), not parameters: it is not trained."""

    def __init__(self, inner: OneStepMap, q_shift, q_scale, p_scale, time_scale):
        super().__init__()
        self.d, self.inner = inner.d, inner
        p = next(inner.parameters())
        kw = {"dtype": p.dtype, "device": p.device}
        for name, v in (("q_shift", q_shift), ("q_scale", q_scale), ("p_scale", p_scale)):
            t = torch.as_tensor(v, dtype=torch.float64).reshape(-1)
            if t.numel() != inner.d:
                raise ValueError(f"normalization.{name}: expected {inner.d} entries, "
                                 f"got {t.numel()}")
            self._exact[name] = t.clone()
            self.register_buffer(name, t.to(**kw))
        self.time_scale = float(time_scale)

    @property
    def _exact(self):
        # The float64 values as the file holds them, so that a module moved to float32 still
        # writes the file's normalisation to the bit.
        if "_exact_values" not in self.__dict__:
            self.__dict__["_exact_values"] = {}
        return self.__dict__["_exact_values"]

    def spec(self):
        norm = {k: self._exact[k].tolist() for k in ("q_shift", "q_scale", "p_scale")}
        norm["time_scale"] = self.time_scale
        return {**self.inner.spec(), "normalization": norm}

    def blocks(self):
        return self.inner.blocks()

    def load_flat(self, theta):
        return self.inner.load_flat(theta)

    @property
    def gamma(self):
        g = self.inner.gamma
        return None if g is None else g / self.time_scale

    def step(self, z, h):
        d = self.d
        zn = torch.cat([(z[:, :d] - self.q_shift) / self.q_scale, z[:, d:] / self.p_scale], dim=1)
        out = self.inner.step(zn, h / self.time_scale)
        return torch.cat([out[:, :d] * self.q_scale + self.q_shift, out[:, d:] * self.p_scale],
                         dim=1)
