#!/usr/bin/env python3
"""Damped systems that are not presets, as trajectory CSV at irregular steps, for
`csympnet fit` (docs/identification.md, "Held-out systems").

    dq/dt = p,   dp/dt = -grad V(q) - gamma p

  pendulum      d = 1, V = -cos q,                                   gamma = 0.1
  henon-heiles  d = 2, V = (q1^2 + q2^2)/2 + q1^2 q2 - q2^3/3,        gamma = 0.03

The solver is classical RK4 with substeps of at most --substep (default 1e-3), not the
conformal splitting of the presets; the script checks itself by solving again with half the
substep and reports the largest difference (Richardson: RK4's error is then about 16/15 of it).
Steps between samples are drawn uniformly from [--h-min, --h-max]; noise, when asked for, is
relative Gaussian per component (sigma times the component's std over the file).

    experiments/heldout_systems.py --system pendulum --out pendulum.csv [--sigma 1e-3]
"""
import argparse
import sys

import numpy as np

SYSTEMS = {
    "pendulum": {"d": 1, "gamma": 0.1, "box": (1.0, 1.0)},
    "henon-heiles": {"d": 2, "gamma": 0.03, "box": (0.4, 0.4)},
}


def grad_v(name, q):
    if name == "pendulum":
        return np.sin(q)
    q1, q2 = q[0], q[1]
    return np.stack([q1 + 2.0 * q1 * q2, q2 + q1 * q1 - q2 * q2])


def field(name, gamma, z):
    d = z.shape[0] // 2
    q, p = z[:d], z[d:]
    return np.concatenate([p, -grad_v(name, q) - gamma * p])


def flow(name, gamma, z, h, substep):
    """RK4 over time h (a vector, one per column of z) in n equal substeps each."""
    n = np.maximum(np.ceil(h / substep), 1.0)
    dt = h / n
    out = z.copy()
    for k in range(int(n.max())):
        active = k < n
        y = out[:, active]
        t = dt[active]
        k1 = field(name, gamma, y)
        k2 = field(name, gamma, y + 0.5 * t * k1)
        k3 = field(name, gamma, y + 0.5 * t * k2)
        k4 = field(name, gamma, y + t * k3)
        out[:, active] = y + t / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--system", choices=sorted(SYSTEMS), required=True)
    ap.add_argument("--trajectories", type=int, default=20)
    ap.add_argument("--steps", type=int, default=12, help="steps per trajectory")
    ap.add_argument("--h-min", type=float, default=0.05)
    ap.add_argument("--h-max", type=float, default=0.2)
    ap.add_argument("--gamma", type=float, default=None, help="default: the system's")
    ap.add_argument("--sigma", type=float, default=0.0)
    ap.add_argument("--substep", type=float, default=1e-3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    spec = SYSTEMS[a.system]
    d, gamma = spec["d"], spec["gamma"] if a.gamma is None else a.gamma
    rng = np.random.default_rng(a.seed)
    m = a.trajectories
    bq, bp = spec["box"]
    z = np.concatenate([rng.uniform(-bq, bq, (d, m)), rng.uniform(-bp, bp, (d, m))])
    times = np.zeros((a.steps + 1, m))
    states = np.zeros((a.steps + 1, 2 * d, m))
    states[0] = z
    worst = 0.0
    for k in range(a.steps):
        h = rng.uniform(a.h_min, a.h_max, m)
        fine = flow(a.system, gamma, states[k], h, a.substep)
        finer = flow(a.system, gamma, states[k], h, a.substep / 2)
        worst = max(worst, float(np.abs(fine - finer).max()))
        states[k + 1] = finer
        times[k + 1] = times[k] + h
    if not np.all(np.isfinite(states)) or np.abs(states).max() > 1e3:
        sys.exit("heldout_systems.py: a trajectory left the bounded region; use a smaller box")
    if a.sigma > 0:
        scale = states.transpose(1, 0, 2).reshape(2 * d, -1).std(axis=1)
        states = states + a.sigma * scale[None, :, None] * rng.standard_normal(states.shape)
    names = [f"q{i + 1}" for i in range(d)] + [f"p{i + 1}" for i in range(d)]
    with open(a.out, "w") as f:
        f.write("traj,t," + ",".join(names) + "\n")
        for j in range(m):
            for k in range(a.steps + 1):
                vals = [repr(float(times[k, j]))] + [repr(float(x)) for x in states[k, :, j]]
                f.write(f"{j}," + ",".join(vals) + "\n")
    print(f"{a.system}: d = {d}, gamma = {gamma}, {m} trajectories x {a.steps} steps in "
          f"[{a.h_min}, {a.h_max}], sigma = {a.sigma}; RK4 substep-halving difference "
          f"{worst:.1e}; wrote {a.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
