#!/usr/bin/python3
"""CSympNet-ID in PyTorch (float64), the peer that `make bench` times csympnet against.

The model is the one src/models/{la_sympnet,g_sympnet,csympnet_id}.cpp define
(docs/derivations.md), written the way a PyTorch user would: an nn.Module with one
nn.Parameter per matrix or vector, autograd for the gradient, torch.optim.AdamW.

    Φ̂_h = S_a ∘ Ψ_h ∘ S_a,  S_a(q, p) = (q, a p),  a = exp(−|β| h / 2)

LA-SympNet(L, m): L linear modules (m sublayers alternating kick p += h S q and drift
q += h S p, S = A + Aᵀ, then p += h b_p, q += h b_q), with an activation module
(k even: p += h a ⊙ σ(q); k odd: q += h a ⊙ σ(p)) after every linear module but the last.
G-SympNet(L, w): L gradient modules, k even a kick p += h Kᵀ(a ⊙ σ(K q + b)), k odd the
drift q += h Kᵀ(a ⊙ σ(K p + b)).

Loss: mean over pairs of ‖z1 − Φ̂_h(z0)‖² (summed over the 2d components), full batch.
Optimiser: AdamW(lr 1e-3, betas (0.9, 0.999), eps 1e-8, weight_decay 5e-4).

Inputs come from `csympnet_bench --peer-export DIR` (bench/peer_export.cpp): for each
preset P, DIR/P-train.f64 (the pairs as raw float64, a row h, z0, z1 per pair), DIR/P-spec.json
(architecture and θ layout), DIR/P-theta0.txt (csympnet's initial θ, 17 digits) and
DIR/P-losses.txt (csympnet's training loss at epochs 1..K from that θ).

It first checks that K epochs from the same θ give the same losses as csympnet's (relative
difference <= --tol), so that the timing compares the same computation, then times epochs.
Prints one JSON object per preset on stdout.

Threads: the thread counts of PyTorch's intra-op pool and of OpenBLAS are set from
--threads before torch is imported.
"""

import argparse
import json
import os
import sys
import time


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--dir", required=True, help="directory written by csympnet_bench --peer-export")
    ap.add_argument("--presets", default="s1,s2,s3,s2-100",
                    help="presets and workloads (s2-100-4k: s2-100 on 4,000 pairs) exported in --dir")
    ap.add_argument("--threads", type=int, default=1, help="torch and BLAS threads (default 1)")
    ap.add_argument("--blas-threads", type=int, default=None,
                    help="OpenBLAS threads when they differ from --threads")
    ap.add_argument("--min-time", type=float, default=2.0,
                    help="seconds of timed epochs per preset and AdamW variant (default 2)")
    ap.add_argument("--tol", type=float, default=1e-12,
                    help="largest accepted relative loss difference to csympnet (default 1e-12)")
    ap.add_argument("--foreach", choices=["auto", "on", "off"], default="auto",
                    help="AdamW implementation: per-tensor loop (off), torch._foreach (on), or "
                    "time both and keep the faster (auto, the default)")
    ap.add_argument("--dgemm", default="100x100x400,1000x1000x1000",
                    help="MxKxN sizes at which to time torch.mm (OpenBLAS dgemm), '' for none")
    return ap.parse_args()


ARGS = parse_args()
BLAS_THREADS = ARGS.threads if ARGS.blas_threads is None else ARGS.blas_threads
os.environ["OMP_NUM_THREADS"] = str(ARGS.threads)
for var in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[var] = str(BLAS_THREADS)

import numpy as np  # noqa: E402
import torch  # noqa: E402

torch.set_num_threads(ARGS.threads)
torch.set_default_dtype(torch.float64)


class LaSympNet(torch.nn.Module):
    """LA-SympNet(L, m) on a batch q, p of shape (N, d); h has shape (N, 1)."""

    def __init__(self, d, layers, sublayers):
        super().__init__()
        self.d, self.layers, self.sublayers = d, layers, sublayers
        self.A = torch.nn.ParameterList(
            [torch.nn.Parameter(torch.zeros(d, d)) for _ in range(layers * sublayers)])
        self.bp = torch.nn.ParameterList([torch.nn.Parameter(torch.zeros(d)) for _ in range(layers)])
        self.bq = torch.nn.ParameterList([torch.nn.Parameter(torch.zeros(d)) for _ in range(layers)])
        self.act = torch.nn.ParameterList(
            [torch.nn.Parameter(torch.zeros(d)) for _ in range(layers - 1)])

    def ordered(self):
        """(parameter, is_matrix) in csympnet's θ order."""
        out = []
        for k in range(self.layers):
            out += [(self.A[k * self.sublayers + i], True) for i in range(self.sublayers)]
            out += [(self.bp[k], False), (self.bq[k], False)]
            if k + 1 < self.layers:
                out.append((self.act[k], False))
        return out

    def forward(self, q, p, h):
        for k in range(self.layers):
            for i in range(self.sublayers):
                a = self.A[k * self.sublayers + i]
                s = a + a.t()  # symmetric, so the row form x @ S equals (S x)ᵀ
                if i % 2 == 0:
                    p = p + h * (q @ s)
                else:
                    q = q + h * (p @ s)
            p = p + h * self.bp[k]
            q = q + h * self.bq[k]
            if k + 1 < self.layers:
                if k % 2 == 0:
                    p = p + h * (self.act[k] * torch.sigmoid(q))
                else:
                    q = q + h * (self.act[k] * torch.sigmoid(p))
        return q, p


class GSympNet(torch.nn.Module):
    """G-SympNet(L, w) on a batch q, p of shape (N, d)."""

    def __init__(self, d, layers, width):
        super().__init__()
        self.d, self.layers, self.width = d, layers, width
        self.K = torch.nn.ParameterList(
            [torch.nn.Parameter(torch.zeros(width, d)) for _ in range(layers)])
        self.a = torch.nn.ParameterList([torch.nn.Parameter(torch.zeros(width)) for _ in range(layers)])
        self.b = torch.nn.ParameterList([torch.nn.Parameter(torch.zeros(width)) for _ in range(layers)])

    def ordered(self):
        out = []
        for k in range(self.layers):
            out += [(self.K[k], True), (self.a[k], False), (self.b[k], False)]
        return out

    def forward(self, q, p, h):
        for k in range(self.layers):
            kmat = self.K[k]
            if k % 2 == 0:
                y = self.a[k] * torch.sigmoid(q @ kmat.t() + self.b[k])
                p = p + h * (y @ kmat)
            else:
                y = self.a[k] * torch.sigmoid(p @ kmat.t() + self.b[k])
                q = q + h * (y @ kmat)
        return q, p


class CSympNetId(torch.nn.Module):
    def __init__(self, core, beta_init=0.1):
        super().__init__()
        self.core = core
        self.beta = torch.nn.Parameter(torch.tensor(beta_init))

    def ordered(self):
        return self.core.ordered() + [(self.beta, False)]

    def forward(self, z, h):
        d = self.core.d
        a = torch.exp(-0.5 * torch.abs(self.beta) * h)  # (N, 1)
        q, p = self.core(z[:, :d], a * z[:, d:], h)
        return torch.cat([q, a * p], dim=1)


def build(spec):
    core = spec["core"]
    if core["type"] == "la":
        c = LaSympNet(spec["d"], core["layers"], core["sublayers"])
    elif core["type"] == "g":
        c = GSympNet(spec["d"], core["layers"], core["width"])
    else:
        raise SystemExit(f"torch_peer: unknown core type {core['type']!r}")
    return CSympNetId(c)


def load_theta(model, theta):
    """Copies csympnet's flat θ (matrices column-major) into the module's parameters."""
    off = 0
    with torch.no_grad():
        for param, is_matrix in model.ordered():
            n = param.numel()
            chunk = torch.from_numpy(theta[off:off + n].copy())
            if is_matrix:
                rows, cols = param.shape
                param.copy_(chunk.reshape(cols, rows).t())  # column-major → (rows, cols)
            else:
                param.copy_(chunk.reshape(param.shape))
            off += n
    if off != theta.size:
        raise SystemExit(f"torch_peer: θ has {theta.size} entries, the module {off}")


def epoch(model, opt, z0, h, z1):
    opt.zero_grad(set_to_none=True)
    residual = model(z0, h) - z1
    loss = (residual * residual).sum() / z0.shape[0]
    loss.backward()
    opt.step()
    return loss


def make_optimizer(model, foreach):
    return torch.optim.AdamW(model.parameters(), lr=1e-3, betas=(0.9, 0.999), eps=1e-8,
                             weight_decay=5e-4, foreach=foreach)


def time_epochs(spec, theta0, z0, h, z1, foreach, min_time):
    model = build(spec)
    load_theta(model, theta0)
    opt = make_optimizer(model, foreach)
    for _ in range(3):  # warm-up: allocator, optimizer state
        epoch(model, opt, z0, h, z1)
    # Batches of epochs, timed until min_time has passed; the median batch is reported.
    n = 1
    while True:
        t0 = time.perf_counter()
        for _ in range(n):
            epoch(model, opt, z0, h, z1)
        dt = time.perf_counter() - t0
        if dt > min_time / 20 or n >= 1 << 20:
            break
        n *= 2
    samples = []
    deadline = time.perf_counter() + min_time
    while time.perf_counter() < deadline or len(samples) < 5:
        t0 = time.perf_counter()
        for _ in range(n):
            epoch(model, opt, z0, h, z1)
        samples.append((time.perf_counter() - t0) / n)
    samples.sort()
    return samples[len(samples) // 2], len(samples) * n


def check_losses(spec, theta0, z0, h, z1, ours):
    model = build(spec)
    load_theta(model, theta0)
    opt = make_optimizer(model, False)
    worst = 0.0
    theirs = []
    for ref in ours:
        loss = epoch(model, opt, z0, h, z1).item()
        theirs.append(loss)
        worst = max(worst, abs(loss - ref) / abs(ref))
    return worst, theirs


def time_dgemm(sizes, min_time=0.5):
    out = {}
    for text in filter(None, sizes.split(",")):
        m, k, n = (int(x) for x in text.split("x"))
        a, b = torch.randn(m, k), torch.randn(k, n)
        c = torch.empty(m, n)
        torch.mm(a, b, out=c)
        reps, best = 1, float("inf")
        deadline = time.perf_counter() + min_time
        while time.perf_counter() < deadline:
            t0 = time.perf_counter()
            for _ in range(reps):
                torch.mm(a, b, out=c)
            dt = (time.perf_counter() - t0) / reps
            best = min(best, dt)
            if dt * reps < 1e-3:
                reps *= 2
        out[text] = 2.0 * m * k * n / best / 1e9
    return out


def blas_libraries():
    with open("/proc/self/maps") as f:
        libs = {line.split()[-1] for line in f if "blas" in line or "lapack" in line}
    return sorted(libs)


def main():
    info = {"kind": "environment", "torch": torch.__version__, "threads": torch.get_num_threads(),
            "blas_threads": BLAS_THREADS,
            "omp_wait_policy": os.environ.get("OMP_WAIT_POLICY", "(default)"),
            "blas": blas_libraries(),
            "dgemm_gflops": time_dgemm(ARGS.dgemm) if ARGS.dgemm else {}}
    print(json.dumps(info), flush=True)
    for preset in filter(None, ARGS.presets.split(",")):
        base = os.path.join(ARGS.dir, preset)
        with open(base + "-spec.json") as f:
            spec = json.load(f)
        theta0 = np.loadtxt(base + "-theta0.txt", dtype=np.float64, ndmin=1)
        ours = np.loadtxt(base + "-losses.txt", dtype=np.float64, ndmin=1).tolist()
        dim = 2 * spec["d"]
        data = np.fromfile(base + "-train.f64", dtype="<f8").reshape(-1, 1 + 2 * dim)
        h = torch.from_numpy(data[:, :1].copy())
        z0 = torch.from_numpy(data[:, 1:1 + dim].copy())
        z1 = torch.from_numpy(data[:, 1 + dim:1 + 2 * dim].copy())

        worst, theirs = check_losses(spec, theta0, z0, h, z1, ours)
        result = {"kind": "preset", "preset": preset, "pairs": int(z0.shape[0]),
                  "params": int(theta0.size), "loss_epochs_checked": len(ours),
                  "loss_rel_diff_max": worst, "loss_ok": worst <= ARGS.tol,
                  "losses_torch": theirs, "losses_csympnet": ours}
        variants = {"off": [False], "on": [True], "auto": [False, True]}[ARGS.foreach]
        timings = {}
        for fe in variants:
            sec, count = time_epochs(spec, theta0, z0, h, z1, fe, ARGS.min_time)
            timings["foreach" if fe else "loop"] = {"seconds_per_epoch": sec, "epochs_timed": count}
        best = min(timings, key=lambda v: timings[v]["seconds_per_epoch"])
        result.update({"timings": timings, "adamw": best,
                       "seconds_per_epoch": timings[best]["seconds_per_epoch"]})
        print(json.dumps(result), flush=True)
        if not result["loss_ok"]:
            print(f"torch_peer: {preset}: loss differs from csympnet's by {worst:.3g} (relative) "
                  f"> {ARGS.tol:g}; the two sides do not compute the same thing", file=sys.stderr)
            sys.exit(1)


if __name__ == "__main__":
    main()
