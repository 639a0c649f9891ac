#!/usr/bin/env python3
"""Every name in tests/long_tests.txt is defined: a GoogleTest one (Suite.Name) by a TEST,
TEST_F or TEST_P of tests/*/*.cpp, a ctest entry (layer.entry) by an add_test of
CMakeLists.txt or python/CMakeLists.txt. A misspelt name would leave that test in `make test`
and run nothing as long. Usage: check_long_tests.py SOURCE
(its self-test, that it finds a planted misspelling, runs first)."""
import re
import sys
from pathlib import Path

DEFINITION = re.compile(r"\bTEST(?:_F|_P)?\(\s*(\w+)\s*,\s*(\w+)\s*\)")
# add_test(NAME python.pytest ...) and add_test(NAME install.pip_${mode} ...) over (venv wheel)
ADD_TEST = re.compile(r"add_test\(NAME\s+([\w.]+)(\$\{mode\})?")
MODES = re.compile(r"foreach\(mode\s+([\w ]+)\)")


def listed(text):
    """(GoogleTest names, ctest entry names)"""
    gtests, entries = [], []
    for line in text.splitlines():
        name = line.split("#", 1)[0].strip()
        if name:
            (gtests if name[0].isupper() else entries).append(name)
    return gtests, entries


def defined_entries(cmake_texts):
    found = set()
    for text in cmake_texts:
        modes = [m for group in MODES.findall(text) for m in group.split()]
        for name, templated in ADD_TEST.findall(text):
            found.update(name + m for m in modes) if templated else found.add(name)
    return found


def defined_gtests(sources):
    found = set()
    for text in sources:
        found.update(f"{a}.{b}" for a, b in DEFINITION.findall(text))
    return found


def missing(listed, defined):
    return [n for n in listed if n not in defined]


def self_test():
    src = ["TEST(Alpha, Works) {}\nTEST_F(Beta, AlsoWorks) {}\n"]
    cmake = ["add_test(NAME experiments.x COMMAND a)\nforeach(mode venv wheel)\n"
             "add_test(NAME install.pip_${mode} COMMAND b)\n"]
    gtests, entries = listed("Alpha.Works  # ok\nBeta.AlsoWork\nexperiments.x\n"
                             "install.pip_wheel\ninstall.pip_egg\n")
    assert missing(gtests, defined_gtests(src)) == ["Beta.AlsoWork"]
    assert missing(entries, defined_entries(cmake)) == ["install.pip_egg"]
    print("self-test: ok")


def main():
    self_test()
    root = Path(sys.argv[1])
    gtests, entries = listed((root / "tests" / "long_tests.txt").read_text())
    sources = [p.read_text(errors="replace") for p in sorted((root / "tests").glob("*/*.cpp"))]
    cmake = [(root / f).read_text() for f in ("CMakeLists.txt", "python/CMakeLists.txt")]
    bad = missing(gtests, defined_gtests(sources))
    for n in bad:
        print(f"tests/long_tests.txt: {n}: no TEST, TEST_F or TEST_P of that name in tests/*/*.cpp")
    bad_entries = missing(entries, defined_entries(cmake))
    for n in bad_entries:
        print(f"tests/long_tests.txt: {n}: no add_test(NAME {n}) in CMakeLists.txt or "
              "python/CMakeLists.txt")
    if bad or bad_entries:
        return 1
    print(f"tests/long_tests.txt: {len(gtests)} GoogleTest names and {len(entries)} ctest "
          "entries, each defined")
    return 0


if __name__ == "__main__":
    sys.exit(main())
