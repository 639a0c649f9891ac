"""`csympnet run --refine lm` without --refine-solver chooses the LM solver by the problem's
size: Ceres' dense_qr where one of its iterations stays small enough to stop within a second of
Ctrl-C (s1), csympnet's blas_normal_cholesky otherwise (s2, 4,111 parameters); report.json's
config says which. A solver named on the command line is kept, and refused if it does not fit."""

import json

import pytest


def refine_config(run_cli, tmp_path, *args):
    out = tmp_path / "run"
    run_cli("run", *args, "--refine", "lm", "--epochs", 1, "--refine-iterations", 1, "-q",
            "--out", out)
    report = json.loads((out / "report.json").read_text())
    return report["config"]["refine"], report["refine"]


@pytest.mark.long
def test_s2_refine_lm_runs_with_the_solver_that_fits(run_cli, tmp_path):
    config, summary = refine_config(run_cli, tmp_path, "--preset", "s2")
    assert config["linear_solver"] == "blas_normal_cholesky"
    assert summary["iterations"] == 1


def test_s1_keeps_dense_qr(run_cli, tmp_path):
    config, _ = refine_config(run_cli, tmp_path, "--preset", "s1")
    assert config["linear_solver"] == "dense_qr"


def test_a_named_solver_is_kept_and_refused_when_too_large(run_cli, tmp_path):
    p = run_cli("run", "--preset", "s2", "--refine", "lm", "--refine-solver", "dense_qr",
                "--epochs", 1, "-q", "--out", tmp_path / "qr", check=False)
    assert p.returncode == 1 and "use --refine-solver blas_normal_cholesky" in p.stderr, p.stderr
