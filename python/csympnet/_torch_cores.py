"""The SympNet cores as torch.nn.Modules: LA-SympNet and G-SympNet (src/models/la_sympnet.hpp,
g_sympnet.hpp; docs/derivations.md). Each reads and writes its block of csympnet's flat θ, whose
matrices are stored column-major."""

from __future__ import annotations

import torch
from torch import nn

# The scale of the normal draws of a fresh core's matrices and amplitudes (kInitStddev of the
# C++ cores); biases and step coefficients start at 0.
INIT_STDDEV = 0.01


def _matrix_from(chunk, rows, cols):
    """A (rows, cols) matrix from its column-major entries."""
    return chunk.reshape(cols, rows).t()


def _matrix_to(mat):
    """The column-major entries of a matrix."""
    return mat.t().reshape(-1)


class Core(nn.Module):
    """A symplectic core Ψ_h acting on q, p of shape (N, d) with steps h of shape (N, 1)."""

    d: int

    def forward(self, z, h):
        """Ψ_h on states z (N, 2d), steps h (N, 1)."""
        q, p = self.flow(z[:, :self.d], z[:, self.d:], h)
        return torch.cat([q, p], dim=1)

    def flow(self, q, p, h):  # pragma: no cover - every core defines it
        raise NotImplementedError

    @property
    def n_params(self):
        return sum(t.numel() for t in self.blocks())


class LASympNet(Core):
    """LA-SympNet(L, m): L linear modules of m shears (kick p += τ S q, drift q += τ S p,
    S = A + Aᵀ, kick first) and biases p += h b_p, q += h b_q; between linear modules k and k+1
    an activation module (k even: p += τ a ⊙ σ(q), odd: q += τ a ⊙ σ(p)). τ = h, or
    τ = h (1 + c h) with one coefficient c per shear and activation module (step_terms = 2).

    θ: per module k, A_{k,0..m-1} (d² each, column-major), b_p, b_q, then a_k if k < L − 1;
    with step_terms = 2 the shears' coefficients (module-major), then the activations'.
    """

    def __init__(self, d, layers, sublayers, step_terms=1, *, dtype=torch.float64, device=None):
        super().__init__()
        if step_terms not in (1, 2):
            raise ValueError(f"step_terms: expected 1 or 2, got {step_terms!r}")
        self.d, self.layers, self.sublayers, self.step_terms = d, layers, sublayers, step_terms
        kw = {"dtype": dtype, "device": device}
        self.A = nn.Parameter(torch.zeros(layers, sublayers, d, d, **kw))
        self.b_p = nn.Parameter(torch.zeros(layers, d, **kw))
        self.b_q = nn.Parameter(torch.zeros(layers, d, **kw))
        self.act = nn.Parameter(torch.zeros(layers - 1, d, **kw))
        if step_terms == 2:
            self.c_shear = nn.Parameter(torch.zeros(layers, sublayers, **kw))
            self.c_act = nn.Parameter(torch.zeros(layers - 1, **kw))

    def spec(self):
        out = {"type": "la", "layers": self.layers, "sublayers": self.sublayers}
        if self.step_terms == 2:
            out["step_terms"] = 2
        return out

    def blocks(self):
        """The parameter blocks in θ order, each as the flat entries θ holds."""
        out = []
        for k in range(self.layers):
            out += [_matrix_to(self.A[k, i]) for i in range(self.sublayers)]
            out += [self.b_p[k], self.b_q[k]]
            if k + 1 < self.layers:
                out.append(self.act[k])
        if self.step_terms == 2:
            out += [self.c_shear.reshape(-1), self.c_act]
        return out

    @torch.no_grad()
    def load_flat(self, theta):
        d, off = self.d, 0

        def take(n):
            nonlocal off
            off += n
            return theta[off - n:off]

        for k in range(self.layers):
            for i in range(self.sublayers):
                self.A[k, i].copy_(_matrix_from(take(d * d), d, d))
            self.b_p[k].copy_(take(d))
            self.b_q[k].copy_(take(d))
            if k + 1 < self.layers:
                self.act[k].copy_(take(d))
        if self.step_terms == 2:
            self.c_shear.copy_(take(self.layers * self.sublayers).reshape(self.layers,
                                                                           self.sublayers))
            self.c_act.copy_(take(self.layers - 1))
        return off

    @torch.no_grad()
    def init_random(self, generator):
        for t in (self.A, self.act):
            t.copy_(INIT_STDDEV * torch.randn(t.shape, generator=generator, dtype=torch.float64))

    def flow(self, q, p, h):
        for k in range(self.layers):
            for i in range(self.sublayers):
                a = self.A[k, i]
                s = a + a.t()  # symmetric: the row form x S is (S x)ᵀ
                tau = h if self.step_terms == 1 else h * (1.0 + self.c_shear[k, i] * h)
                if i % 2 == 0:
                    p = p + tau * (q @ s)
                else:
                    q = q + tau * (p @ s)
            p = p + h * self.b_p[k]
            q = q + h * self.b_q[k]
            if k + 1 < self.layers:
                tau = h if self.step_terms == 1 else h * (1.0 + self.c_act[k] * h)
                if k % 2 == 0:
                    p = p + tau * (self.act[k] * torch.sigmoid(q))
                else:
                    q = q + tau * (self.act[k] * torch.sigmoid(p))
        return q, p


class GSympNet(Core):
    """G-SympNet(L, w): L gradient modules, k even a kick p += h Kᵀ(a ⊙ σ(K q + b)), k odd a
    drift q += h Kᵀ(a ⊙ σ(K p + b)), K ∈ R^{w×d}.

    θ: per module k, K_k (w × d, column-major), a_k (w), b_k (w).
    """

    def __init__(self, d, layers, width, *, dtype=torch.float64, device=None):
        super().__init__()
        self.d, self.layers, self.width = d, layers, width
        kw = {"dtype": dtype, "device": device}
        self.K = nn.Parameter(torch.zeros(layers, width, d, **kw))
        self.a = nn.Parameter(torch.zeros(layers, width, **kw))
        self.b = nn.Parameter(torch.zeros(layers, width, **kw))

    def spec(self):
        return {"type": "g", "layers": self.layers, "width": self.width}

    def blocks(self):
        out = []
        for k in range(self.layers):
            out += [_matrix_to(self.K[k]), self.a[k], self.b[k]]
        return out

    @torch.no_grad()
    def load_flat(self, theta):
        d, w, off = self.d, self.width, 0
        for k in range(self.layers):
            self.K[k].copy_(_matrix_from(theta[off:off + w * d], w, d))
            off += w * d
            self.a[k].copy_(theta[off:off + w])
            self.b[k].copy_(theta[off + w:off + 2 * w])
            off += 2 * w
        return off

    @torch.no_grad()
    def init_random(self, generator):
        for t in (self.K, self.a):
            t.copy_(INIT_STDDEV * torch.randn(t.shape, generator=generator, dtype=torch.float64))

    def flow(self, q, p, h):
        for k in range(self.layers):
            kmat = self.K[k]
            if k % 2 == 0:
                y = self.a[k] * torch.sigmoid(q @ kmat.t() + self.b[k])
                p = p + h * (y @ kmat)
            else:
                y = self.a[k] * torch.sigmoid(p @ kmat.t() + self.b[k])
                q = q + h * (y @ kmat)
        return q, p
