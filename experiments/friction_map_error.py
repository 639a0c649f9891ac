#!/usr/bin/python3
"""How far the library map with Coulomb friction is from the exact motion, at given parameters.

    q'' = -omega^2 q - gamma q' - mu sign(q')

The map (core {"type": "library", "terms": ["q1^2"], "dissipation": ["coulomb(p1)"]}, the
order and substeps given, friction "in_kicks" or "split") with the true parameters is rolled
out from (q0, v0) over `points` samples at step h, beside the exact record of
experiments/idbench/friction.py (closed form between reversals). Prints the largest |q| and
|q'| error for each substep count: the integrator's own error, with no fit in between.

    /usr/bin/python3 experiments/friction_map_error.py --omega 2.388 --gamma 0.1385 \\
        --mu 0.1598 --h 0.08769 --points 457 --order 6 --substeps 1,2,4,8

Needs the Python module built (build/python, `make` builds it).
"""
import argparse
import json
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "build", "python"))
sys.path.insert(0, HERE)

from idbench import friction  # noqa: E402


def positive(text):
    v = float(text)
    if not v > 0:
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return v


def substep_list(text):
    try:
        out = [int(x) for x in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected counts such as 1,2,4, got {text!r}")
    if not out or any(n < 1 or n > 4096 for n in out):
        raise argparse.ArgumentTypeError(f"expected counts in 1..4096, got {text!r}")
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--omega", type=positive, required=True)
    ap.add_argument("--gamma", type=float, required=True)
    ap.add_argument("--mu", type=float, required=True)
    ap.add_argument("--h", type=positive, required=True)
    ap.add_argument("--points", type=int, default=400)
    ap.add_argument("--q0", type=float, default=1.3)
    ap.add_argument("--v0", type=float, default=0.4)
    ap.add_argument("--order", type=int, choices=(2, 4, 6), default=6)
    ap.add_argument("--substeps", type=substep_list, default=[1, 2, 4, 8])
    ap.add_argument("--friction", choices=("in_kicks", "split"), default="in_kicks")
    a = ap.parse_args()
    if a.points < 2 or a.points > 10**6:
        ap.error("--points: expected 2..1000000")
    if a.mu < 0 or 2 * a.omega <= abs(a.gamma):
        ap.error("expected mu >= 0 and an underdamped oscillator (|gamma| < 2 omega)")
    import csympnet._core as core
    exact = friction.simulate("coulomb", a.omega, a.gamma, a.mu, a.q0, a.v0, a.h, a.points)
    theta = np.array([1.0, 0.5 * a.omega ** 2, a.gamma, a.mu])
    print(f"omega {a.omega} gamma {a.gamma} mu {a.mu} h {a.h}, {a.points} samples, order "
          f"{a.order}, friction {a.friction}")
    for n in a.substeps:
        spec = {"type": "csympnet", "d": 1, "beta_init": 0.1,
                "core": {"type": "library", "terms": ["q1^2"], "dissipation": ["coulomb(p1)"],
                         "friction": a.friction, "order": a.order, "substeps": n,
                         "mass": "full"}}
        model = core.from_spec(json.dumps(spec), theta, "{}")
        z = np.array([[a.q0, a.v0]])
        err = np.zeros(2)
        for k in range(1, a.points):
            z = np.asarray(model.predict(z, np.array([a.h]), False)).reshape(1, 2)
            err = np.maximum(err, np.abs(z[0] - exact[k]))
        print(f"substeps {n:5d}: largest error in q {err[0]:.3g}, in q' {err[1]:.3g}")


if __name__ == "__main__":
    main()
