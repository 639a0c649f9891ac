# Builds csympnet._core with the project's own CMake build (the targets csympnet_python, the
# library and the bindings, and csympnet, the command line; no tests) and puts the module beside
# python/csympnet/*.py and the command line in csympnet/_bin/, where the `csympnet` console
# script and `python -m csympnet` run it (python/csympnet/_cli.py). The metadata is in
# pyproject.toml; the version is CMakeLists.txt's project version.
#
# Environment:
#   CSYMPNET_CMAKE_BUILD_DIR  an existing CMake build directory of this source tree to build
#                             the module in (it is reused as configured: nothing is compiled
#                             that is already up to date there). Default: build/pip/cmake,
#                             configured here (Release, no tests, no benchmarks).
#   CSYMPNET_CMAKE_ARGS       extra arguments for that configure step (space-separated), e.g.
#                             "-DCMAKE_CXX_COMPILER_LAUNCHER=ccache".
#   CMAKE_BUILD_PARALLEL_LEVEL  compile jobs (default: the number of CPUs).
#   CSYMPNET_BUNDLE_CLI=0     leave the command line out (the `csympnet` command then looks
#                             for it elsewhere: CSYMPNET_CLI, PATH).
import os
import re
import shlex
import shutil
import subprocess
import sys
import sysconfig

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = os.path.dirname(os.path.abspath(__file__))


def project_version():
    with open(os.path.join(ROOT, "CMakeLists.txt"), encoding="utf-8") as f:
        match = re.search(r"project\(\s*csympnet\s+VERSION\s+([0-9][0-9.]*)", f.read())
    if not match:
        sys.exit("setup.py: no 'project(csympnet VERSION x.y.z' in CMakeLists.txt")
    return match.group(1)


def build_dir_of_env():
    path = os.environ.get("CSYMPNET_CMAKE_BUILD_DIR")
    return os.path.abspath(path) if path else None


class CMakeBuild(build_ext):
    """Builds the one extension, csympnet._core, with CMake instead of compiling sources."""

    def build_extension(self, ext):
        cmake = shutil.which("cmake")
        if cmake is None:
            raise RuntimeError("csympnet: cmake not found (Debian: apt-get install cmake, or "
                               "run scripts/install-deps.sh)")
        build_dir = build_dir_of_env()
        if build_dir:
            if not os.path.isfile(os.path.join(build_dir, "CMakeCache.txt")):
                raise RuntimeError(f"csympnet: CSYMPNET_CMAKE_BUILD_DIR={build_dir} is not a "
                                   "configured CMake build directory")
        else:
            build_dir = os.path.join(ROOT, "build", "pip", "cmake")
            args = [cmake, "-S", ROOT, "-B", build_dir, "-DCMAKE_BUILD_TYPE=Release",
                    "-DCSYMPNET_BUILD_TESTS=OFF", "-DCSYMPNET_BUILD_BENCH=OFF",
                    "-DCSYMPNET_BUILD_PYTHON=ON", "-DCSYMPNET_REQUIRE_PYTHON=ON",
                    f"-DPython3_EXECUTABLE={sys.executable}"]
            args += shlex.split(os.environ.get("CSYMPNET_CMAKE_ARGS", ""))
            subprocess.run(args, check=True)
        env = dict(os.environ)
        env.setdefault("CMAKE_BUILD_PARALLEL_LEVEL", str(os.cpu_count() or 1))
        bundle_cli = os.environ.get("CSYMPNET_BUNDLE_CLI", "1") != "0"
        targets = ["csympnet_python"] + (["csympnet"] if bundle_cli else [])
        try:
            subprocess.run([cmake, "--build", build_dir, "--target", *targets],
                           check=True, env=env)
        except subprocess.CalledProcessError as e:
            raise RuntimeError(
                f"csympnet: building the targets {' '.join(targets)} in {build_dir} failed; if "
                "CMake said 'Python module NOT built', that build directory was configured "
                "without Python 3 headers, NumPy or pybind11") from e

        # The module CMake built must be for this interpreter (the same ABI tag).
        suffix = sysconfig.get_config_var("EXT_SUFFIX")
        built = os.path.join(build_dir, "python", "csympnet", "_core" + suffix)
        if not os.path.isfile(built):
            found = sorted(f for f in os.listdir(os.path.dirname(built)) if f.startswith("_core"))
            raise RuntimeError(
                f"csympnet: {build_dir} holds {found or 'no _core module'}, not _core{suffix} for "
                f"{sys.executable}; configure it with -DPython3_EXECUTABLE={sys.executable} "
                "(or unset CSYMPNET_CMAKE_BUILD_DIR)")
        target = self.get_ext_fullpath(ext.name)
        os.makedirs(os.path.dirname(target), exist_ok=True)
        shutil.copyfile(built, target)
        shutil.copymode(built, target)
        if bundle_cli:
            cli = os.path.join(build_dir, "bin", "csympnet")
            bundled = os.path.join(os.path.dirname(target), "_bin", "csympnet")
            os.makedirs(os.path.dirname(bundled), exist_ok=True)
            shutil.copyfile(cli, bundled)
            shutil.copymode(cli, bundled)


# setuptools' scratch files (build_base, the egg-info) stay out of the source tree's python/:
# under the CMake build directory given, or under build/pip.
scratch = os.path.join(build_dir_of_env() or os.path.join(ROOT, "build", "pip"), "setuptools")
os.makedirs(scratch, exist_ok=True)

setup(
    version=project_version(),
    ext_modules=[Extension("csympnet._core", sources=[])],
    cmdclass={"build_ext": CMakeBuild},
    options={"build": {"build_base": scratch}, "egg_info": {"egg_base": scratch}},
    zip_safe=False,
)
