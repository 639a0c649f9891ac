"""Dry friction and drag from Python: `identify` and `CSympNetID` give the dissipation that
`csympnet fit` writes (one C++ pipeline), with the same numbers to the bit, and the option is
checked by name."""

import json
import math
import subprocess

import numpy as np
import pytest

import csympnet


def coulomb_oscillator(omega=2.0, gamma=0.1, mu=0.1, h=0.1, n=301, starts=((1.0, 0.0), (-1.4, 0.5),
                                                                          (2.0, 0.0)),
                       sigma=2e-3, seed=0):
    """Exact records of q'' = -ω² q - γ q' - μ sign(q'): closed form between reversals,
    sticking when |ω² q| ≤ μ at a reversal."""
    rng = np.random.default_rng(seed)
    w2, wd = omega * omega, math.sqrt(omega * omega - gamma * gamma / 4)
    trajs = []
    for q, v in starts:
        z = []
        for _ in range(n):
            z.append((q, v))
            left = h
            while left > 0:
                if v == 0.0 and w2 * abs(q) <= mu:
                    break
                s = (1.0 if v > 0 else -1.0) if v != 0.0 else (-1.0 if q > 0 else 1.0)
                c = -mu * s / w2
                a = q - c
                b = (v + 0.5 * gamma * a) / wd
                cc, dd = v, a * wd + 0.5 * gamma * b
                ph = math.fmod(math.atan2(cc, dd), math.pi)
                ph = ph + math.pi if ph < 0 else ph
                ph = ph + math.pi if ph <= 1e-15 else ph
                tz = ph / wd
                t = min(left, tz)
                e = math.exp(-0.5 * gamma * t)
                q = c + e * (a * math.cos(wd * t) + b * math.sin(wd * t))
                v = e * (cc * math.cos(wd * t) - dd * math.sin(wd * t)) if t < tz else 0.0
                left -= t
        z = np.array(z)
        z += sigma * z.std(axis=0) * rng.standard_normal(z.shape)
        trajs.append(z)
    t = np.arange(n) * h
    return t, trajs


def test_identify_and_the_estimator_report_friction_as_the_cli_does(tmp_path, cli):
    t, trajs = coulomb_oscillator()
    r = csympnet.identify(trajs, [t] * len(trajs), observed="states")
    assert r.identified, r.reasons
    kinds = [d["kind"] for d in r.dissipation]
    assert kinds == ["viscous", "coulomb"], r.dissipation
    mu = r.dissipation[1]
    assert mu["dof"] == 1 and abs(mu["value"] - 0.1) < 0.01
    assert mu["low"] <= 0.1 <= mu["high"]
    assert r.dissipation[0]["value"] == r.gamma
    assert "plus dry friction mu = " in r.dissipation_sentence
    assert r.model.hyperparams["core"]["dissipation"] == ["coulomb(p1)"]

    est = csympnet.CSympNetID(observed="states").fit(trajs, [t] * len(trajs))
    assert est.dissipation_ == r.dissipation
    # The same selection table on both paths, with the report's rows.
    assert est.model_selection_ == r.model_selection == r.report["model_selection"]
    assert r.model_selection and all(row["chosen"] != row["runner_up"]
                                     for row in r.model_selection)
    assert est.get_params()["dissipation"] == "auto"

    # The CLI on the same records: the same terms to the bit.
    path = tmp_path / "friction.csv"
    with open(path, "w") as f:
        f.write("traj,t,q1,p1\n")
        for k, z in enumerate(trajs):
            for ti, (q, p) in zip(t, z):
                f.write("%d,%.17g,%.17g,%.17g\n" % (k, ti, q, p))
    out = tmp_path / "fit"
    subprocess.run([cli, "fit", str(path), "--out", str(out), "--quiet", "--no-figures"],
                   check=True, capture_output=True)
    cli = json.loads((out / "report.json").read_text())
    assert cli["dissipation"]["terms"] == r.dissipation


@pytest.mark.long
def test_viscous_only_on_request_and_bad_choices_are_named():
    t, trajs = coulomb_oscillator(n=151)
    # Viscous alone cannot explain dry friction: the amplitude check rejects the model.
    with pytest.warns(csympnet.ModelRejectedWarning, match="dry \\(Coulomb\\) friction"):
        r = csympnet.identify(trajs, [t] * len(trajs), observed="states", dissipation="viscous")
    assert [d["kind"] for d in r.dissipation] == ["viscous"]
    assert r.report["config"]["dissipation"] == "viscous"
    with pytest.raises(csympnet.Error, match="dissipation"):
        csympnet.identify(trajs, [t] * len(trajs), observed="states", dissipation="coulomb")
