#!/usr/bin/python3
"""Checks that a change to the options, the recipes or the report of `csympnet fit` and
`csympnet train` moved nothing: runs both commands with two binaries (before and after) on the
same small data and options, and compares report.json (every field but wall times), model.json
(byte for byte), what they print, and the message and exit status of refused options. With
--python-before/--python-after it also compares `csympnet.fit` (parameters, meta, errors)
and `csympnet.identify` (parameters, γ̂, interval, errors).

    bench/compare_fit_reports.py --before OLD/csympnet --after build/bin/csympnet
        [--python-before OLD_PYTHON_DIR --python-after build/python]

Budgets are small (a few hundred epochs): this checks the plumbing, not the science. Exit
status 1 if anything differs.
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

from compare_reports import differences, strip_timing  # the same rules as for `run`

# (name, data file key, arguments after the data)
FITS = [
    ("fit s1 identify", "fit", "s1", ["--epochs", "300", "--lm-iterations", "20"]),
    ("fit s1 classic", "fit", "s1", ["--recipe", "classic", "--epochs", "300"]),
    ("fit s1 classic lm", "fit", "s1",
     ["--recipe", "classic", "--epochs", "300", "--refine", "lm", "--refine-iterations", "20",
      "--bootstrap", "10"]),
    ("fit s1 classic lbfgs", "fit", "s1",
     ["--recipe", "classic", "--epochs", "300", "--refine", "lbfgs", "--refine-iterations", "20",
      "--bootstrap", "0"]),
    ("fit s1 classic no bootstrap", "fit", "s1",
     ["--recipe", "classic", "--epochs", "300", "--bootstrap", "0", "--no-warm-start"]),
    ("fit s2 classic blas", "fit", "s2",
     ["--recipe", "classic", "--epochs", "200", "--refine", "lm", "--refine-solver",
      "blas_normal_cholesky", "--refine-iterations", "10", "--bootstrap", "0"]),
    ("fit s2 classic normal", "fit", "s2",
     ["--recipe", "classic", "--epochs", "200", "--refine", "lm", "--refine-solver",
      "dense_normal_cholesky", "--refine-iterations", "5", "--bootstrap", "0"]),
    ("fit s1 sympnet", "fit", "s1", ["--model", "sympnet", "--epochs", "300"]),
    ("fit s1 trajectories", "fit", "s1traj",
     ["--recipe", "classic", "--epochs", "200", "--refine-iterations", "10", "--bootstrap",
      "10"]),
    ("fit s1 identify options", "fit", "s1traj",
     ["--epochs", "60", "--seed", "3", "--lr", "2e-3", "--val-fraction", "0.3", "--blocks", "5",
      "--level", "0.9", "--lm-iterations", "5"]),
    ("fit s1 identify one-step", "fit", "s1traj",
     ["--epochs", "40", "--window", "2", "--loss", "one-step", "--no-normalize", "--dof-scales",
      "fixed", "--lm-iterations", "4", "--core", "la:2:3"]),
    ("train s1", "train", "s1", ["--epochs", "300"]),
    ("train s1 val", "train", "s1", ["--epochs", "300", "--val", "{s1val}", "--lr", "3e-3",
                                     "--lr-schedule", "constant", "--val-every", "7"]),
    ("train s2 lm", "train", "s2",
     ["--epochs", "200", "--refine", "lm", "--refine-iterations", "10", "--bootstrap", "10",
      "--warm-start", "--seed", "7", "--val-fraction", "0.3", "--no-beta-decay"]),
    ("train s2 auto", "train", "s2", ["--epochs", "200", "--refine", "auto"]),
    ("train s1 sympnet", "train", "s1", ["--model", "sympnet", "--epochs", "200",
                                         "--core", "g:2:8"]),
]

# Refused options: (command, arguments after the data); message and exit status must match.
BAD = [
    ("fit", ["--blocks", "2"]),
    ("fit", ["--level", "1.5"]),
    ("fit", ["--window", "99"]),
    ("fit", ["--recipe", "classic", "--refine", "bogus"]),
    ("fit", ["--recipe", "classic", "--refine-solver", "bogus"]),
    ("fit", ["--recipe", "classic", "--refine-solver", "dense_qr"]),
    ("fit", ["--recipe", "classic", "--bootstrap", "-5"]),
    ("fit", ["--recipe", "classic", "--bootstrap", "5"]),
    ("fit", ["--refine", "lm"]),
    ("fit", ["--lr", "0"]),
    ("fit", ["--recipe", "bogus"]),
    ("train", ["--refine", "bogus"]),
    ("train", ["--refine-solver", "qr"]),
    ("train", ["--bootstrap", "-5"]),
    ("train", ["--lr", "0"]),
    ("train", ["--lr", "nan"]),
    ("train", ["--epochs", "0"]),
    ("train", ["--refine-iterations", "0"]),
    ("train", ["--val-fraction", "1"]),
    ("train", ["--beta-init", "0"]),
    ("train", ["--model", "bogus"]),
    ("train", ["--lr-schedule", "linear"]),
    ("train", ["--val-every", "0"]),
    ("train", ["--model", "sympnet", "--bootstrap", "10", "--epochs", "10"]),
    ("train", ["--refine", "auto", "--refine-solver", "dense_qr"]),
    ("train", ["--beta-init", "1e9", "--epochs", "10"]),
    ("train", ["--seed", "-1"]),
    ("fit", ["--model", "sympnet", "--refine-solver", "dense_qr"]),
    ("fit", ["--model", "sympnet", "--refine", "lm", "--refine-solver", "dense_qr",
             "--epochs", "20", "--refine-iterations", "3"]),
]


def untimed(text, out_dir):
    # Wall times in the summary lines ("in 1.23 s", "1.2 s"), and the output directory.
    text = text.replace(out_dir, "OUT")
    return re.sub(r"\d+(\.\d+)?(e[-+]?\d+)? ?s\b", "T s", text)


def run_cli(binary, command, data, args, out):
    cmd = ["nice", "-n", "19", binary, command]
    cmd += ["--data", data] if command == "train" else [data]
    cmd += [*args, "--out", out, "-q"]
    p = subprocess.run(cmd, capture_output=True, text=True)
    result = {"rc": p.returncode, "stdout": untimed(p.stdout, out),
              "stderr": untimed(p.stderr, out)}
    for name in ("report.json", "model.json"):
        path = os.path.join(out, name)
        if os.path.exists(path):
            with open(path) as f:
                text = f.read()
            result[name] = strip_timing(json.loads(text)) if name == "report.json" else text
    return result


def compare(label, before, after):
    diffs = []
    for key in ("rc", "stdout", "stderr", "model.json"):
        if before.get(key) != after.get(key):
            diffs.append(f"{key}: {before.get(key)!r} != {after.get(key)!r}")
    diffs += list(differences(before.get("report.json"), after.get("report.json")))
    print(f"{label:40s} {'identical' if not diffs else 'DIFFERENT'}", flush=True)
    for d in diffs[:8]:
        print("    " + d[:400])
    return bool(diffs)


PY_SNIPPET = r"""
import json, sys, warnings
import numpy as np
import csympnet
z = np.loadtxt(sys.argv[1], delimiter=",", skiprows=1)
d = (z.shape[1] - 1) // 4
h, z0, z1 = z[:, 0], z[:, 1:1 + 2 * d], z[:, 1 + 2 * d:]
cases = json.loads(sys.argv[2])
out = []
for kw in cases:
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            m = csympnet.fit(z0, z1, h, **kw)
        meta = {k: v for k, v in m.meta.items()}
        out.append({"theta": [repr(float(x)) for x in m.theta], "gamma": repr(m.gamma),
                    "meta": meta, "training": {k: v for k, v in (m.training or {}).items()
                                               if not k.endswith("seconds")}})
    except Exception as e:
        out.append({"error": type(e).__name__ + ": " + str(e)})
print(json.dumps(out, sort_keys=True, default=str))
"""

PY_CASES = [
    {"epochs": 200},
    {"epochs": 200, "refine": "lm", "refine_iterations": 10, "bootstrap": 10},
    {"epochs": 200, "refine": "lbfgs", "refine_iterations": 10, "bootstrap": 0,
     "warm_start": False},
    {"epochs": 200, "refine": "none", "bootstrap": 0, "lr": 2e-3, "weight_decay": 0.0,
     "lr_schedule": "constant", "lr_final_fraction": 0.5, "val_every": 5},
    {"epochs": 100, "model": "sympnet"},
    {"epochs": 100, "refine": "lm", "refine_solver": "blas_normal_cholesky", "bootstrap": 0},
    {"refine": "bogus"},
    {"refine_solver": "bogus", "refine": "lm"},
    {"refine_solver": "dense_qr"},
    {"bootstrap": -5},
    {"bootstrap": 5, "epochs": 10},
    {"lr": 0},
    {"epochs": 0},
    {"val_fraction": 1.0},
    {"beta_init": 0.0},
    {"lr_schedule": "linear"},
    {"weight_decay": -1.0},
    {"lr_final_fraction": 0.0},
    {"lr_final_fraction": 2.0, "epochs": 10},
    {"model": "sympnet", "bootstrap": 10, "epochs": 10},
    {"threads": 0},
    {"refine_iterations": 0},
    {"val_every": 0},
    {"warm_start": 1},
]


# Python's identify on a damped oscillator built here, with these keywords.
PY_ID_SNIPPET = r"""
import json, sys, warnings
import numpy as np
import csympnet
t = np.linspace(0.0, 20.0, 201)
z = np.stack([np.exp(-0.05 * t) * np.cos(t), -np.exp(-0.05 * t) * np.sin(t)], axis=1)
out = []
for kw in json.loads(sys.argv[1]):
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = csympnet.identify(z, t, **kw)
        out.append({"theta": [repr(float(x)) for x in r.model.params], "gamma": repr(r.gamma),
                    "interval": repr(getattr(r, "interval", None))})
    except Exception as e:
        out.append({"error": type(e).__name__ + ": " + str(e)})
print(json.dumps(out, sort_keys=True, default=str))
"""

PY_ID_CASES = [
    {"epochs": 40},
    {"epochs": 40, "seed": 5, "blocks": 6, "level": 0.9, "lm_iterations": 3, "window": 2,
     "loss": "one-step"},
    {"epochs": 30, "normalize": False, "core": "la:2:3", "dof_scales": "fixed"},
    {"epochs": 10, "blocks": 2},
    {"epochs": 10, "level": 2.0},
]


def run_python_identify(pydir):
    env = dict(os.environ, PYTHONPATH=pydir)
    p = subprocess.run(["nice", "-n", "19", "/usr/bin/python3", "-c", PY_ID_SNIPPET,
                        json.dumps(PY_ID_CASES)], capture_output=True, text=True, env=env)
    if p.returncode != 0:
        return [{"crash": p.stderr[-2000:]}]
    return json.loads(p.stdout)


def run_python(pydir, data):
    env = dict(os.environ, PYTHONPATH=pydir)
    p = subprocess.run(["nice", "-n", "19", "/usr/bin/python3", "-c", PY_SNIPPET, data,
                        json.dumps(PY_CASES)], capture_output=True, text=True, env=env)
    if p.returncode != 0:
        return [{"crash": p.stderr[-2000:]}]
    return json.loads(p.stdout)


def compare_python(name, cases, before, after):
    """Prints one line per case; returns how many differ (a crash on either side differs)."""
    bad = 0
    for i, (b, a) in enumerate(zip(before, after)):
        label = f"{name} {json.dumps(cases[i])}" if i < len(cases) else name
        diffs = list(differences(b, a))
        print(f"{label[:60]:60s} {'identical' if not diffs else 'DIFFERENT'}", flush=True)
        for d in diffs[:8]:
            print("    " + d[:400])
        bad += bool(diffs)
    return bad + abs(len(before) - len(after))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", required=True, help="csympnet binary built from the old code")
    ap.add_argument("--after", required=True, help="csympnet binary built from the new code")
    ap.add_argument("--python-before", help="directory of the old Python package")
    ap.add_argument("--python-after", help="directory of the new Python package")
    args = ap.parse_args()
    bad = 0
    with tempfile.TemporaryDirectory() as tmp:
        data = {}
        for key, gen in {"s1": ["--preset", "s1", "--n", "60"],
                         "s1val": ["--preset", "s1", "--split", "val", "--n", "20"],
                         "s2": ["--preset", "s2", "--n", "40"],
                         "s1traj": ["--preset", "s1", "--split", "test", "--n", "3"]}.items():
            data[key] = os.path.join(tmp, key + ".csv")
            subprocess.run([args.before, "generate", *gen, "--out", data[key]], check=True,
                           stdout=subprocess.DEVNULL)
        for i, (label, command, key, extra) in enumerate(FITS):
            extra = [x.format(**data) for x in extra]
            before = run_cli(args.before, command, data[key], extra,
                             os.path.join(tmp, "a", str(i)))
            after = run_cli(args.after, command, data[key], extra, os.path.join(tmp, "b", str(i)))
            bad += compare(label, before, after)
        for command in ("fit", "train", "run"):
            texts = [subprocess.run([b, command, "--help"], capture_output=True,
                                    text=True).stdout.replace(b, "BIN")
                     for b in (args.before, args.after)]
            diffs = [] if texts[0] == texts[1] else ["help text differs"]
            print(f"{command + ' --help':40s} {'identical' if not diffs else 'DIFFERENT'}",
                  flush=True)
            bad += bool(diffs)
        for i, (command, extra) in enumerate(BAD):
            label = f"{command} {' '.join(extra)}"
            before = run_cli(args.before, command, data["s1"], extra,
                             os.path.join(tmp, "ea", str(i)))
            after = run_cli(args.after, command, data["s1"], extra,
                            os.path.join(tmp, "eb", str(i)))
            bad += compare(label, before, after)
        if args.python_before and args.python_after:
            bad += compare_python("python", PY_CASES,
                                  run_python(args.python_before, data["s1"]),
                                  run_python(args.python_after, data["s1"]))
            bad += compare_python("python identify", PY_ID_CASES,
                                  run_python_identify(args.python_before),
                                  run_python_identify(args.python_after))
    print("all fit/train results identical (timing fields aside)" if not bad
          else f"{bad} case(s) differ")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
