"""ctest install.pip_venv and install.pip_wheel: pip, offline, against this source tree.

  pip_check.py venv  --source S --build-dir B --work W
      a fresh venv (--system-site-packages: NumPy is Debian's), `pip install
      --no-build-isolation --no-deps --no-index S` reusing the CMake build directory B, then
      import csympnet from a directory outside S and fit and predict; run the `csympnet`
      command and `python -m csympnet`, which run the bundled command line.
  pip_check.py wheel --source S --build-dir B --work W
      `pip wheel` S into W/wheels, check what the wheel holds, install it into a fresh venv
      and import it the same way.

Run it with the interpreter the build directory's module was compiled for (/usr/bin/python3).
"""
import argparse
import glob
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
import zipfile

# What the installed package must do, run by the venv's interpreter from a scratch directory.
CHECK = r"""
import os, sys
import importlib.metadata
import csympnet
venv, version = sys.argv[1], sys.argv[2]
where = os.path.realpath(csympnet.__file__)
assert where.startswith(os.path.realpath(venv) + os.sep), f"csympnet imported from {where}"
assert csympnet.__version__ == version, (csympnet.__version__, version)
assert importlib.metadata.version("csympnet") == version
model = csympnet.fit(*csympnet.generate("s1", "train"), epochs=20)
z1 = model.predict([0.5, -0.2], 0.1)
assert z1.shape == (2,) and all(abs(v) < 10 for v in z1), z1
assert model.gamma > 0
print(f"csympnet {csympnet.__version__} from {os.path.dirname(where)}: gamma_hat {model.gamma:.4f}")
"""


def project_version(source):
    with open(os.path.join(source, "CMakeLists.txt"), encoding="utf-8") as f:
        return re.search(r"project\(\s*csympnet\s+VERSION\s+([0-9.]+)", f.read()).group(1)


def run(args, **kw):
    print("+", " ".join(args), flush=True)
    start = time.monotonic()
    subprocess.run(args, check=True, **kw)
    print(f"  ({time.monotonic() - start:.1f} s)", flush=True)


def make_venv(path):
    # The interpreter running this script is the one the module was built for.
    run([sys.executable, "-m", "venv", "--system-site-packages", path])
    return os.path.join(path, "bin", "python")


def check_import(python, venv, version, source):
    # A directory outside the source tree, so that nothing there can shadow the package.
    with tempfile.TemporaryDirectory(prefix="csympnet-import-") as cwd:
        assert not os.path.realpath(cwd).startswith(os.path.realpath(source) + os.sep)
        run([python, "-c", CHECK, venv, version], cwd=cwd)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("mode", choices=["venv", "wheel"])
    parser.add_argument("--source", required=True)
    parser.add_argument("--build-dir", required=True)
    parser.add_argument("--work", required=True)
    a = parser.parse_args()
    source, work = os.path.abspath(a.source), os.path.abspath(a.work)
    version = project_version(source)
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)

    # pip reaches no index (--no-index), keeps no wheel cache, builds with the interpreter's
    # own setuptools (--no-build-isolation) and reuses the build directory's compiled library.
    os.environ["CSYMPNET_CMAKE_BUILD_DIR"] = os.path.abspath(a.build_dir)
    os.environ["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    os.environ.pop("PYTHONPATH", None)
    os.environ["PYTHONNOUSERSITE"] = "1"
    offline = ["--no-build-isolation", "--no-deps", "--no-index", "--no-cache-dir"]

    venv = os.path.join(work, "venv")
    python = make_venv(venv)
    if a.mode == "venv":
        run([python, "-m", "pip", "install", *offline, source])
    else:
        wheels = os.path.join(work, "wheels")
        run([python, "-m", "pip", "wheel", *offline, "-w", wheels, source])
        found = glob.glob(os.path.join(wheels, "*.whl"))
        assert len(found) == 1 and os.path.basename(found[0]).startswith(f"csympnet-{version}-"), found
        with zipfile.ZipFile(found[0]) as whl:
            names = set(whl.namelist())
            metadata = whl.read(f"csympnet-{version}.dist-info/METADATA").decode()
        expected = {f"csympnet/{os.path.basename(p)}"
                    for p in glob.glob(os.path.join(source, "python", "csympnet", "*.py"))}
        expected.add("csympnet/_core" + sysconfig.get_config_var("EXT_SUFFIX"))
        expected.add("csympnet/_bin/csympnet")
        expected.add(f"csympnet-{version}.dist-info/LICENSE")
        missing = expected - names
        assert not missing, f"the wheel lacks {sorted(missing)}; it holds {sorted(names)}"
        assert "License: MIT" in metadata and f"Version: {version}" in metadata, metadata
        print(f"{os.path.basename(found[0])}: {len(names)} files, {os.path.getsize(found[0])} bytes")
        run([python, "-m", "pip", "install", "--no-deps", "--no-index", "--no-cache-dir", found[0]])
    check_import(python, venv, version, source)
    check_command(venv, version)


def check_command(venv, version):
    """The console script `csympnet` and `python -m csympnet` run the bundled command line."""
    bundled = glob.glob(os.path.join(venv, "lib", "python*", "site-packages", "csympnet", "_bin",
                                     "csympnet"))
    assert len(bundled) == 1 and os.access(bundled[0], os.X_OK), bundled
    env = dict(os.environ)
    env.pop("CSYMPNET_CLI", None)
    env["PATH"] = "/usr/bin:/bin"  # nothing but the venv's own command can answer
    for cmd in ([os.path.join(venv, "bin", "csympnet"), "--version"],
                [os.path.join(venv, "bin", "python"), "-m", "csympnet", "--version"]):
        with tempfile.TemporaryDirectory(prefix="csympnet-cli-") as cwd:
            out = subprocess.run(cmd, check=True, cwd=cwd, env=env, capture_output=True,
                                 text=True).stdout
        assert version in out, (cmd, out)
        print(f"{' '.join(os.path.basename(c) for c in cmd)}: {out.strip()}")


if __name__ == "__main__":
    main()
