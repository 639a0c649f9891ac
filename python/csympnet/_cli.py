"""The `csympnet` command installed by pip, and `python -m csympnet`: both run the C++ command
line (`csympnet --help`), which `pip install` bundles in the package as csympnet/_bin/csympnet.

Where it looks, in order: the environment variable CSYMPNET_CLI (a path to the program); the
bundled copy; the build tree's bin/csympnet when the package is imported from a CMake build
directory (PYTHONPATH=build/python); <prefix>/bin/csympnet when the package was installed by
`cmake --install` into <prefix>; a compiled `csympnet` on PATH.
"""

import os
import sys

_HELP = (
    "csympnet: the command-line program is not part of this installation.\n"
    "  Build it from the source tree: `make build` (or `cmake --build build --target csympnet`)\n"
    "  gives build/bin/csympnet; `cmake --install build --prefix ~/.local` puts it in\n"
    "  ~/.local/bin. Then put it on PATH, or set CSYMPNET_CLI=/path/to/csympnet.\n"
    "  `pip install .` from the source tree bundles it (docs/install.md).")


def _is_program(path):
    """An executable compiled program (not a script such as this package's own launcher)."""
    if not path or not os.path.isfile(path) or not os.access(path, os.X_OK):
        return False
    try:
        with open(path, "rb") as f:
            return f.read(4) == b"\x7fELF"
    except OSError:
        return False


def find_cli(environ=None, package_dir=None, path=None):
    """The path of the csympnet program, or None when there is none (see the module's
    docstring for where it looks)."""
    environ = os.environ if environ is None else environ
    package_dir = os.path.dirname(os.path.abspath(__file__)) if package_dir is None else package_dir
    given = environ.get("CSYMPNET_CLI")
    if given:
        return given if _is_program(given) else None
    up = lambda n: os.path.abspath(os.path.join(package_dir, *[os.pardir] * n))
    candidates = [os.path.join(package_dir, "_bin", "csympnet"),
                  # <build>/python/csympnet -> <build>/bin/csympnet
                  os.path.join(up(2), "bin", "csympnet"),
                  # `cmake --install`: <prefix>/lib/python3.X/dist-packages/csympnet ->
                  # <prefix>/bin/csympnet
                  os.path.join(up(4), "bin", "csympnet")]
    for c in candidates:
        if _is_program(c):
            return c
    search = environ.get("PATH", "") if path is None else path
    for d in search.split(os.pathsep):
        c = os.path.join(d, "csympnet") if d else None
        if c and _is_program(c):
            return c
    return None


def main(argv=None):
    """Runs the csympnet program with argv (default: this process's arguments); its exit
    status is the command's."""
    argv = sys.argv[1:] if argv is None else list(argv)
    cli = find_cli()
    if cli is None:
        given = os.environ.get("CSYMPNET_CLI")
        if given:
            print(f"csympnet: CSYMPNET_CLI={given} is not an executable csympnet program",
                  file=sys.stderr)
        else:
            print(_HELP, file=sys.stderr)
        return 127
    sys.stdout.flush()
    sys.stderr.flush()
    os.execv(cli, [cli] + argv)
    return 0  # not reached


__all__ = ["find_cli", "main"]
