#!/usr/bin/env python3
"""Tutorial: from a CSV of one long measured trajectory to γ̂ ± interval and a rollout figure.

The measurement is a damped pendulum recorded for 60 s at about 20 Hz: the angle in degrees,
the angular velocity in degrees per second (a velocity, not a momentum), time in seconds, with
sensor noise and a jittery sample clock. It stands in for your own file; step 1 writes it,
steps 2-5 are what you would run on yours. docs/tutorial.md walks through the same steps.

    PYTHONPATH=build/python /usr/bin/python3 examples/tutorial_own_data.py [--out DIR]

`--write-record PATH` writes step 1's CSV alone and stops (no csympnet needed): that is how
examples/pendulum_record.csv, the record `make demo` fits, was made.
"""

import argparse
import os

import numpy as np


# The truth, which the fit does not see: θ'' = −(g/L) sin θ − γ θ'.
GAMMA = 0.12  # 1/s
G_OVER_L = 9.81 / 0.8  # a 0.8 m pendulum
DEG = 180.0 / np.pi


def pendulum_field(z):
    """(θ, θ') in radians ↦ (θ', θ'') for a batch z of shape (N, 2)."""
    return np.c_[z[:, 1], -G_OVER_L * np.sin(z[:, 0]) - GAMMA * z[:, 1]]


def integrate(z0, times, max_substep=2e-4):
    """Classical RK4 from z0 through `times`, substeps ≤ max_substep (local error ~1e-15)."""
    out = [np.asarray(z0, dtype=float)]
    for h in np.diff(times):
        n = int(np.ceil(h / max_substep))
        s, y = h / n, out[-1][None, :]
        for _ in range(n):
            k1 = pendulum_field(y)
            k2 = pendulum_field(y + 0.5 * s * k1)
            k3 = pendulum_field(y + 0.5 * s * k2)
            k4 = pendulum_field(y + s * k3)
            y = y + s / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(y[0])
    return np.array(out)


def write_measurement(path):
    """Step 1 (stands in for your data): a CSV with your own column names and units."""
    rng = np.random.default_rng(7)
    times = np.cumsum(np.r_[0.0, 0.05 + rng.uniform(-0.005, 0.005, 1199)])  # jittery 20 Hz
    z = integrate([np.radians(50.0), 0.0], times) * DEG  # degrees, degrees per second
    z += rng.normal(0.0, [0.05, 0.2], z.shape)  # sensor noise: 0.05°, 0.2°/s
    np.savetxt(path, np.c_[times, z], delimiter=",", fmt="%.10g", comments="",
               header="time_s,angle_deg,angular_velocity_deg_s")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default="tutorial-out", help="output directory")
    parser.add_argument("--write-record", metavar="PATH",
                        help="write step 1's CSV to PATH and stop")
    args = parser.parse_args()
    if args.write_record:
        write_measurement(args.write_record)
        return
    import csympnet  # not needed to write the record
    from csympnet import plot
    os.makedirs(args.out, exist_ok=True)
    csv = os.path.join(args.out, "pendulum.csv")
    write_measurement(csv)

    # Step 2: read the columns by name. The state is (q, p) = (angle, angular velocity): a
    # velocity works as well as a momentum, because the fit learns each coordinate's scale.
    data = np.genfromtxt(csv, delimiter=",", names=True)
    t = data["time_s"]
    z = np.c_[data["angle_deg"], data["angular_velocity_deg_s"]]

    # Step 3: fit on the first 45 s; keep the last 15 s to test the model on.
    fit_rows = t <= 45.0
    est = csympnet.CSympNetID(seed=0, observed="states").fit(z[fit_rows], t[fit_rows])
    if not est.identified_:
        raise SystemExit("not identified: " + "; ".join(est.reasons_))
    low, high = est.gamma_interval_
    print(f"gamma_hat = {est.gamma_:.5f} 1/s, 95% interval [{low:.5f}, {high:.5f}] "
          f"(true {GAMMA}; core {est.report_['choices']['core']})")

    # Step 4: score it on the held-out 15 s, which it never saw.
    held_t, held_z = t[~fit_rows], z[~fit_rows]
    scores = est.model_.score(held_z, held_t)
    print(f"held out: one-step R² {scores['one_step_r2']:.5f}, rollout NRMSE "
          f"{scores['rollout_nrmse']:.4f}, valid for {scores['valid_time_mean']:.1f} of "
          f"{held_t[-1] - held_t[0]:.1f} s")

    # Step 5: the rollout from the held-out segment's first state, against the measurement.
    rollout = est.simulate(held_z[0], held_t)
    figure = os.path.join(args.out, "tutorial-rollout")
    plot.rollout_figure(held_t - held_t[0], {"csympnet": rollout}, held_z, path=figure,
                        units={"t": "s", "q": "deg", "p": "deg/s"},
                        title=f"Held-out 15 s: γ̂ = {est.gamma_:.4f} 1/s (true {GAMMA})")
    est.model_.save(os.path.join(args.out, "model.json"))
    print(f"wrote {figure}.png, {figure}.pdf and {args.out}/model.json")

    # What this example promises, checked, so that `make test` notices if it stops holding.
    assert low <= GAMMA <= high, "the interval should cover the true damping rate here"
    assert scores["rollout_nrmse"] < 0.1 and scores["valid_fraction_mean"] > 0.5
    # The record shipped beside this file (what `make demo` and docs/tutorial.md fit) is the
    # one step 1 writes.
    shipped = os.path.join(os.path.dirname(os.path.abspath(__file__)), "pendulum_record.csv")
    if os.path.exists(shipped):
        ours, theirs = (np.loadtxt(f, delimiter=",", skiprows=1) for f in (csv, shipped))
        assert ours.shape == theirs.shape and np.allclose(ours, theirs, rtol=1e-9, atol=1e-12), \
            f"{shipped} is not what write_measurement() writes: regenerate it with --write-record"


if __name__ == "__main__":
    main()
