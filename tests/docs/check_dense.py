#!/usr/bin/env python3
"""Eigen's dense factorisations are instantiated in one file, src/core/dense.cpp
(core/dense.hpp, docs/architecture.md): each costs 3 to 16 CPU s of compile in every file that
instantiates it. Checks that no other file of the library, the CLI or the Python module names
one, and that the checker sees something: a planted use must be caught, and dense.cpp's own
uses must be found.

Usage: check_dense.py [REPO]   (exit 0 when only dense.cpp instantiates them; else each line)
"""
import os
import re
import sys

USE = re.compile(
    r"\b(JacobiSVD|BDCSVD|SelfAdjointEigenSolver|ComplexEigenSolver|EigenSolver|FullPivLU|"
    r"PartialPivLU|CompleteOrthogonalDecomposition|ColPivHouseholderQR|FullPivHouseholderQR|"
    r"HouseholderQR|LDLT|LLT)\s*<|\.(inverse|determinant|ldlt|llt|colPivHouseholderQr|"
    r"householderQr|fullPivLu|partialPivLu|jacobiSvd|bdcSvd|completeOrthogonalDecomposition)\(\)")
HOME = os.path.join("src", "core", "dense.cpp")
ALLOWED = {HOME, os.path.join("include", "csympnet", "core", "dense.hpp")}


def uses(repo):
    found, home = [], 0
    for top in ("src", "include", "apps", os.path.join("python", "src")):
        for dirpath, _, files in os.walk(os.path.join(repo, top)):
            for name in sorted(files):
                if not name.endswith((".cpp", ".hpp", ".h")):
                    continue
                path = os.path.join(dirpath, name)
                rel = os.path.relpath(path, repo)
                with open(path, encoding="utf-8") as f:
                    for number, line in enumerate(f, 1):
                        code = line.split("//")[0]
                        if not USE.search(code):
                            continue
                        if rel == HOME:
                            home += 1
                        elif rel not in ALLOWED:
                            found.append(f"{rel}:{number}: {line.strip()}")
    return found, home


def self_test():
    for planted in ("const Eigen::LDLT<Matrix> f(a);", "x = a.colPivHouseholderQr().solve(b);",
                    "Eigen::SelfAdjointEigenSolver<Matrix> e(u);", "m.inverse()"):
        assert USE.search(planted), planted
    for clean in ("dense::Ldlt f(a);", "// Eigen's LDLT", "dense::inverse(a)"):
        assert not USE.search(clean.split("//")[0]), clean


def main():
    repo = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..")
    self_test()
    found, home = uses(os.path.abspath(repo))
    if home < 8:
        print(f"FAIL: only {home} uses found in {HOME}; the checker is not reading the code")
        return 1
    for f in found:
        print(f)
    if found:
        print(f"FAIL: {len(found)} use(s) of Eigen's factorisations outside {HOME}: call "
              "core/dense.hpp instead")
        return 1
    print(f"ok: Eigen's factorisations only in {HOME} ({home} uses)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
