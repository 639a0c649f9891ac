"""`python -m csympnet` and the pip-installed `csympnet` command run the C++ command line
(csympnet._cli); when there is none, they say how to get it. The pip-installed command and the
bundled program are checked by ctest install.pip_venv and install.pip_wheel."""

import os
import subprocess
import sys

import csympnet
from csympnet import _cli


def test_python_m_csympnet_runs_the_command_line(tmp_path):
    env = dict(os.environ)
    env.pop("CSYMPNET_CLI", None)  # found as the build tree's bin/csympnet
    out = subprocess.run([sys.executable, "-m", "csympnet", "--version"], cwd=tmp_path, env=env,
                         capture_output=True, text=True, check=True).stdout
    assert csympnet.__version__ in out
    # Arguments and the exit status pass through: a usage error is exit 2.
    bad = subprocess.run([sys.executable, "-m", "csympnet", "no-such-command"], cwd=tmp_path,
                         env=env, capture_output=True, text=True)
    assert bad.returncode == 2 and "subcommand" in bad.stderr


def test_where_the_program_is_looked_for(tmp_path):
    program = os.environ.get("CSYMPNET_CLI") or _cli.find_cli()
    assert program and _cli.find_cli({"CSYMPNET_CLI": program}) == program
    # A script named csympnet (such as pip's launcher itself) is never taken for the program.
    script = tmp_path / "bin" / "csympnet"
    script.parent.mkdir()
    script.write_text("#!/bin/sh\nexit 0\n")
    script.chmod(0o755)
    lonely = tmp_path / "site" / "csympnet"
    lonely.mkdir(parents=True)
    assert _cli.find_cli({}, package_dir=str(lonely), path=str(script.parent)) is None
    assert _cli.find_cli({"CSYMPNET_CLI": str(script)}, package_dir=str(lonely)) is None
    bundled = lonely / "_bin" / "csympnet"
    bundled.parent.mkdir()
    bundled.write_bytes(open(program, "rb").read())
    bundled.chmod(0o755)
    assert _cli.find_cli({}, package_dir=str(lonely), path="") == str(bundled)


def test_without_a_program_it_says_how_to_get_one(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(_cli, "find_cli", lambda: None)
    monkeypatch.delenv("CSYMPNET_CLI", raising=False)
    assert _cli.main(["--version"]) == 127
    err = capsys.readouterr().err
    assert "make build" in err and "CSYMPNET_CLI" in err and "cmake --install" in err
