"""One rule per option, the library's: the CLI and Python refuse the same values with the same
problem, each naming the option as its user spells it (--val-fraction / val_fraction).

Each row: the command line and the Python call that give one option the same bad value, the
option's two spellings, and what the library expects. The CLI must exit 2 (a usage error)
before any work; Python must raise csympnet.Error (a ValueError).
"""

import subprocess

import numpy as np
import pytest

import csympnet

# (id, CLI command and arguments, Python call name, Python keywords, CLI name, Python name,
#  the problem after the name, the same on both sides)
RANGE_ROWS = [
    # csympnet.fit is `csympnet train`/`fit --recipe classic`: FitConfig's rules.
    ("fit-epochs", ["train", "{data}", "--epochs", "0"], "fit", {"epochs": 0},
     "--epochs", "epochs", "'0' is out of range; expected a number from 1 to 100000000"),
    ("fit-val-every", ["train", "{data}", "--val-every", "0"], "fit", {"val_every": 0},
     "--val-every", "val_every", "'0' is out of range; expected a number from 1 to 100000000"),
    ("fit-lr", ["train", "{data}", "--lr", "20"], "fit", {"lr": 20.0},
     "--lr", "lr", "'20' is out of range; expected a number from 1e-12 to 10"),
    ("fit-val-fraction", ["train", "{data}", "--val-fraction", "1"], "fit", {"val_fraction": 1.0},
     "--val-fraction", "val_fraction", "'1' is out of range; expected a number from 0.01 to 0.99"),
    ("fit-beta-init", ["train", "{data}", "--beta-init", "0"], "fit", {"beta_init": 0.0},
     "--beta-init", "beta_init", "'0' is zero; expected a nonzero number"),
    ("fit-refine-iterations", ["train", "{data}", "--refine-iterations", "0"], "fit",
     {"refine_iterations": 0}, "--refine-iterations", "refine_iterations",
     "'0' is out of range; expected a number from 1 to 100000000"),
    ("fit-bootstrap", ["train", "{data}", "--bootstrap", "5"], "fit", {"bootstrap": 5},
     "--bootstrap", "bootstrap",
     "'5' is out of range; expected 0 (off) or a number from 10 to 1000000: a percentile "
     "interval needs at least 10 replicates"),
    ("fit-threads", ["train", "{data}", "--threads", "257"], "fit", {"threads": 257},
     "--threads", "threads", "'257' is out of range; expected a number from 1 to 256"),
    ("fit-chunk-pairs", ["train", "{data}", "--chunk-pairs", "2000000000"], "fit",
     {"chunk_pairs": 2000000000}, "--chunk-pairs", "chunk_pairs",
     "'2000000000' is out of range; expected a number from 0 to 1000000000"),
    ("fit-batch-size", ["train", "{data}", "--batch-size", "2000000000000"], "fit",
     {"batch_size": 2000000000000}, "--batch-size", "batch_size",
     "'2000000000000' is out of range; expected a number from 0 to 1000000000000"),
    # csympnet.identify is `csympnet fit`: IdentifyConfig's rules.
    ("identify-window", ["fit", "{data}", "--window", "65"], "identify", {"window": 65},
     "--window", "window", "'65' is out of range; expected a number from 0 to 64"),
    ("identify-lm-iterations", ["fit", "{data}", "--lm-iterations", "100001"], "identify",
     {"lm_iterations": 100001}, "--lm-iterations", "lm_iterations",
     "'100001' is out of range; expected a number from 0 to 100000"),
    ("identify-blocks", ["fit", "{data}", "--blocks", "2"], "identify", {"blocks": 2},
     "--blocks", "blocks", "'2' is out of range; expected a number from 3 to 10000"),
    ("identify-level", ["fit", "{data}", "--level", "1"], "identify", {"level": 1.0},
     "--level", "level", "'1' is out of range; expected a number from 0.5 to 0.9999"),
    ("identify-val-fraction", ["fit", "{data}", "--val-fraction", "0"], "identify",
     {"val_fraction": 0.0}, "--val-fraction", "val_fraction",
     "'0' is out of range; expected a number from 0.01 to 0.99"),
    ("identify-lr", ["fit", "{data}", "--lr", "20"], "identify", {"lr": 20.0},
     "--lr", "lr", "'20' is out of range; expected a number from 1e-12 to 10"),
    ("identify-threads", ["fit", "{data}", "--threads", "300"], "identify", {"threads": 300},
     "--threads", "threads", "'300' is out of range; expected a number from 1 to 256"),
    # csympnet.run is `csympnet run`: RunConfig's rules.
    ("run-sigma", ["run", "--preset", "s1", "--sigma", "11"], "run", {"sigma": 11.0},
     "--sigma", "sigma", "'11' is out of range; expected a number from 0 to 10"),
    ("run-val-every", ["run", "--preset", "s1", "--val-every", "0"], "run", {"val_every": 0},
     "--val-every", "val_every", "'0' is out of range; expected a number from 1 to 100000000"),
    ("run-lr", ["run", "--preset", "s1", "--lr", "20"], "run", {"lr": 20.0},
     "--lr", "lr", "'20' is out of range; expected a number from 1e-12 to 10"),
]

# Rules between options: the problem names the other option, spelt by each front end.
DEPENDENCY_ROWS = [
    ("refine-solver-needs-lm",
     ["train", "{data}", "--refine", "auto", "--refine-solver", "dense_qr"], "fit",
     {"refine_solver": "dense_qr"},
     "--refine-solver: needs --refine lm: --refine auto (fit's default) chooses the solver by "
     "the model's size",
     "refine_solver: needs refine=\"lm\": refine=\"auto\" (fit's default) chooses the solver "
     "by the model's size"),
    ("bootstrap-needs-csympnet",
     ["train", "{data}", "--model", "sympnet", "--bootstrap", "10"], "fit",
     {"model": "sympnet", "bootstrap": 10},
     "--bootstrap: needs --model csympnet (the only model here with a damping rate)",
     "bootstrap: needs model=\"csympnet\" (the only model here with a damping rate)"),
]


@pytest.fixture(scope="module")
def data_file(tmp_path_factory, run_cli):
    path = tmp_path_factory.mktemp("rules") / "s1.csv"
    run_cli("generate", "--preset", "s1", "--n", "20", "--out", path)
    return str(path)


def _cli_refusal(cli, args, data_file, out):
    # train takes its data with --data; fit takes it as the first argument.
    words = [w.format(data=data_file) for w in args]
    if words[0] == "train":
        words = ["train", "--data", *words[1:]]
    p = subprocess.run([cli, *words, "--out", str(out), "-q"], capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 2, f"exit {p.returncode}: {p.stderr}"
    assert not out.exists(), "refused after the output directory was made"
    return p.stderr.splitlines()[0]


def _python_refusal(call, kwargs):
    z0, z1, h = csympnet.generate("s1", "train", n=20)
    t = np.linspace(0.0, 10.0, 101)
    z = np.stack([np.exp(-0.05 * t) * np.cos(t), -np.exp(-0.05 * t) * np.sin(t)], axis=1)
    with pytest.raises(csympnet.Error) as e:
        if call == "fit":
            csympnet.fit(z0, z1, h, **kwargs)
        elif call == "identify":
            csympnet.identify(z, t, **kwargs)
        else:
            csympnet.run("s1", **kwargs)
    return str(e.value)


@pytest.mark.parametrize("row", RANGE_ROWS, ids=[r[0] for r in RANGE_ROWS])
def test_the_same_range_is_refused_by_each_front_end_in_its_own_spelling(
        row, cli, data_file, tmp_path):
    _, args, call, kwargs, cli_name, py_name, problem = row
    assert _cli_refusal(cli, args, data_file, tmp_path / "o") == f"{cli_name}: {problem}"
    assert _python_refusal(call, kwargs) == f"{py_name}: {problem}"


@pytest.mark.parametrize("row", DEPENDENCY_ROWS, ids=[r[0] for r in DEPENDENCY_ROWS])
def test_rules_between_options_name_both_in_each_front_ends_spelling(
        row, cli, data_file, tmp_path):
    _, args, call, kwargs, cli_message, py_message = row
    assert _cli_refusal(cli, args, data_file, tmp_path / "o") == cli_message
    assert _python_refusal(call, kwargs) == py_message


def test_python_choices_are_the_librarys_names():
    # The closed sets Python checks before calling the library are the library's lists.
    assert csympnet._fit.REFINE_CHOICES == ("auto", "none", "lm", "lbfgs")
    assert csympnet._fit.RUN_RECIPES == ("default", "paper")
    assert csympnet._identify.DOF_SCALES == ("auto", "learned", "fixed")
    assert csympnet._identify.LOSSES == ("balanced", "one-step")
    with pytest.raises(ValueError, match="dof_scales: expected one of auto, learned, fixed"):
        csympnet.identify(np.zeros((5, 2)), np.arange(5.0), dof_scales="free")
    with pytest.raises(ValueError, match="recipe: expected one of default, paper"):
        csympnet.run("s1", recipe="fast")
