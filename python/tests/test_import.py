"""The package imports, is the compiled one, and plot.py stands alone."""

import os
import subprocess
import sys
import textwrap

import csympnet
from conftest import SOURCE_DIR


def test_package_is_the_compiled_module():
    assert csympnet._core.__file__.endswith(".so")
    assert csympnet.__version__.count(".") == 2
    assert issubclass(csympnet.Error, ValueError)


def test_public_api_has_docstrings():
    for name in csympnet.__all__:
        obj = getattr(csympnet, name)
        assert obj.__doc__ and obj.__doc__.strip(), f"csympnet.{name} has no docstring"
    for name in ("predict", "rollout", "jacobian", "diagnostics", "structure", "save"):
        assert getattr(csympnet.Model, name).__doc__, f"Model.{name} has no docstring"


def test_plot_loads_by_path_without_the_extension(tmp_path):
    # What the reproduce script does: importlib on python/csympnet/plot.py, with no csympnet
    # package importable at all.
    script = textwrap.dedent(f"""
        import importlib.util, sys
        spec = importlib.util.spec_from_file_location(
            "standalone_plot", {str(SOURCE_DIR / "python" / "csympnet" / "plot.py")!r})
        plot = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(plot)
        assert not any(m == "csympnet" or m.startswith("csympnet.") for m in sys.modules), sys.modules
        import numpy as np
        t = np.linspace(0, 1, 11)
        z = np.c_[np.cos(t), -np.sin(t)]
        plot.rollout_figure(t, {{"csympnet": z + 1e-3}}, z, path={str(tmp_path / "fig")!r})
    """)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env,
                       cwd=tmp_path, timeout=120)
    assert p.returncode == 0, p.stderr
    assert (tmp_path / "fig.png").stat().st_size > 0
    assert (tmp_path / "fig.pdf").stat().st_size > 0


def test_torch_is_optional():
    # With torch unimportable (None in sys.modules), csympnet imports and csympnet.torch says
    # what to install.
    script = textwrap.dedent("""
        import sys
        sys.modules["torch"] = None
        import csympnet
        assert csympnet.load
        try:
            import csympnet.torch
        except ImportError as e:
            assert "python3-torch" in str(e) and "pip install torch" in str(e), e
        else:
            raise AssertionError("csympnet.torch imported without torch")
    """)
    p = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                       env=dict(os.environ), timeout=60)
    assert p.returncode == 0, p.stderr
