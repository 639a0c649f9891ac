"""Shared fixtures: the CLI binary, small data sets and small trained models.

Run from the build tree (ctest does this): PYTHONPATH=<build>/python, CSYMPNET_CLI=<build>/bin/csympnet.
"""

import os
import subprocess
from pathlib import Path

import pytest

import csympnet

SOURCE_DIR = Path(__file__).resolve().parents[2]
EPOCHS = 300  # tiny budgets keep the suite at a few seconds


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "long: a test of several seconds whose stages quicker tests run; ctest runs "
        "the marked ones as python.pytest_long (label long: `make test-long`, CI), the rest as "
        "python.pytest (`make test`)")


def pytest_report_header(config):
    return f"csympnet {csympnet.__version__} from {Path(csympnet.__file__).parent}"


@pytest.fixture(scope="session")
def cli():
    """Path of the csympnet binary: $CSYMPNET_CLI, else <build>/bin/csympnet beside the
    build-tree package (<build>/python/csympnet)."""
    path = os.environ.get("CSYMPNET_CLI") or str(
        Path(csympnet.__file__).resolve().parents[2] / "bin" / "csympnet")
    assert os.access(path, os.X_OK), f"csympnet CLI not found at {path}; set CSYMPNET_CLI"
    return path


@pytest.fixture(scope="session")
def run_cli(cli):
    """Runs the CLI with arguments; returns stdout; fails the test on a nonzero exit."""

    def run(*args, check=True):
        p = subprocess.run([cli, *map(str, args)], capture_output=True, text=True, timeout=120)
        if check:
            assert p.returncode == 0, f"csympnet {' '.join(map(str, args))} failed:\n{p.stderr}"
        return p

    return run


@pytest.fixture(scope="session")
def s1_pairs():
    return csympnet.generate("s1", "train")


@pytest.fixture(scope="session")
def s1_model(s1_pairs):
    model = csympnet.fit(*s1_pairs, epochs=EPOCHS)
    model.meta["system"] = csympnet.systems["s1"]["system"]
    return model


@pytest.fixture(scope="session")
def s2_model():
    """A d = 10 model (LA core with full matrices: batched products differ from single ones)."""
    # Any trained d = 10 model serves; no second stage or interval is needed.
    return csympnet.fit(*csympnet.generate("s2", "train", n=40), epochs=30, refine="none",
                        bootstrap=0)
