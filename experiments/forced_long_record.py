#!/usr/bin/env python3
"""A long driven record for timing `csympnet fit`: one of the forced plan's systems
(experiments/idbench/forced.py) driven by a random-phase odd multisine, positions only with
noise, written as t,q1..qd,u1..um. The forced plan's records are 4,096 samples; this writes as
many as asked (65,536 by default: the size at which a forced fit's cost is judged).

  /usr/bin/python3 experiments/forced_long_record.py --out long.csv [--samples 65536]
      [--system duffing] [--seed 1]
  csympnet fit long.csv --out fit -q --no-figures      # then: timings.json, report.json

The truth (gamma, B, the noise) is printed, and written beside the record as OUT.json.
"""
import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from idbench.forced import (GAMMA_RATIO, OMEGA_SUBSTEP, TARGET_AMPLITUDE, band,  # noqa: E402
                            forced_system, linear_rms, multisine, simulate, system_accel,
                            write_forced_csv)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="the CSV to write (refused if it exists)")
    ap.add_argument("--samples", type=int, default=65536, help="samples (default 65536)")
    ap.add_argument("--system", default="duffing", help="duffing, pendulum or duffing-chain")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--period", type=int, default=4096,
                    help="the multisine's period in samples (default 4096)")
    args = ap.parse_args(argv)
    if args.samples < 2 * args.period or args.period < 64:
        sys.exit("--samples must be at least twice --period, and --period at least 64")
    if os.path.exists(args.out):
        sys.exit(f"{args.out}: exists; not overwritten")
    try:
        s = forced_system(args.system)
    except ValueError as e:
        sys.exit(f"--system: {e}")
    rng = np.random.default_rng([args.seed, 777])
    r_lo, r_hi = GAMMA_RATIO[s["name"]]
    gamma = float(s["omega_max"] * math.exp(rng.uniform(math.log(r_lo), math.log(r_hi))))
    h = 2 * math.pi / s["omega_max"] / float(rng.uniform(20.0, 40.0))
    lo, hi = band(s)
    a_lo, a_hi = TARGET_AMPLITUDE[s["name"]]
    target = float(math.exp(rng.uniform(math.log(a_lo), math.log(a_hi))))
    sigma = float(math.exp(rng.uniform(math.log(1e-3), math.log(1e-2))))
    periods = 1 + int(math.ceil(args.samples / args.period))  # the first settles the transient
    u, omegas = multisine(rng, args.period, h, lo, hi, periods)
    u *= target / linear_rms(s, gamma, omegas, math.sqrt(2.0 / omegas.size))
    force = np.einsum("dm,nm->nd", s["B"], u[:, None])[:, :, None]
    substeps = max(1, int(math.ceil(h * s["omega_max"] * math.sqrt(1.0 + 3.0 * (2.0 * target) ** 2)
                                    / OMEGA_SUBSTEP)))
    z = np.zeros((s["d"], 1))
    q, _ = simulate(system_accel(s, gamma), z, z, force, h, substeps)
    q = q[args.period:args.period + args.samples, :, 0]
    q = q + sigma * q.std(axis=0)[None, :] * rng.standard_normal(q.shape)
    uu = u[args.period:args.period + args.samples, None]
    write_forced_csv(args.out, h * np.arange(q.shape[0]), q, uu)
    truth = {"system": s["name"], "gamma": gamma, "B": s["B"].tolist(), "h": h,
             "sigma_relative": sigma, "samples": int(q.shape[0]), "seed": args.seed,
             "period": args.period}
    with open(args.out + ".json", "w") as f:
        json.dump(truth, f, indent=1)
    print(json.dumps(truth))


if __name__ == "__main__":
    main()
