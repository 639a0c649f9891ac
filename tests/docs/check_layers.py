#!/usr/bin/env python3
"""The layers of docs/architecture.md, checked on the code: every #include of a csympnet header
(or of another layer's private header, "../LAYER/...") in include/csympnet/LAYER and src/LAYER
must name a layer strictly below LAYER, so that data and calls flow one way and no circle can
form. identify and paper stand side by side: neither may include the other.

Also checks that the checker sees something: a planted upward include must be caught.

Usage: check_layers.py [REPO]   (exit 0 when the graph holds; else each offending line)
"""
import os
import re
import sys

# Rank of each layer: an include must go to a strictly lower rank (same-rank layers are
# siblings that may not include each other). "experiments" holds only the forwarding headers
# of the earlier layout, above everything.
RANK = {
    "core": 0,
    "io": 1, "kernels": 1, "systems": 1,
    "integrators": 2,
    "data": 3,
    "models": 4,
    "train": 5,
    "diagnostics": 6,
    "identify": 7, "paper": 7,
    "experiments": 8,
}
INCLUDE = re.compile(r'^\s*#\s*include\s+"(?:csympnet/|\.\./(?:\.\./)*(?:src/)?)([a-z_]+)/')


def violations(repo):
    found, seen = [], 0
    for top in ("include/csympnet", "src"):
        base = os.path.join(repo, top)
        for layer in sorted(os.listdir(base)):
            folder = os.path.join(base, layer)
            if not os.path.isdir(folder):
                continue
            if layer not in RANK:
                found.append(f"{top}/{layer}: a layer docs/architecture.md does not rank")
                continue
            for dirpath, _, files in os.walk(folder):
                for name in sorted(files):
                    path = os.path.join(dirpath, name)
                    with open(path, encoding="utf-8") as f:
                        lines = f.read().split("\n")
                    for number, line in enumerate(lines, 1):
                        m = INCLUDE.match(line)
                        if not m or m.group(1) == layer:
                            continue
                        seen += 1
                        target = m.group(1)
                        if target not in RANK or RANK[target] >= RANK[layer]:
                            rel = os.path.relpath(path, repo)
                            found.append(f"{rel}:{number}: {layer} includes {target}: "
                                         f"{line.strip()}")
    return found, seen


def self_test():
    """A planted include of paper from identify, and of train from models, must be caught."""
    for upward in (("identify", "paper"), ("models", "train")):
        m = INCLUDE.match(f'#include "csympnet/{upward[1]}/x.hpp"')
        assert m and RANK[m.group(1)] >= RANK[upward[0]], upward
    m = INCLUDE.match('#include "../kernels/targets.hpp"')
    assert m and m.group(1) == "kernels"


def main():
    repo = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..")
    self_test()
    found, seen = violations(os.path.abspath(repo))
    if seen < 100:
        print(f"FAIL: only {seen} cross-layer includes seen; the checker is not reading the code")
        return 1
    for v in found:
        print(v)
    if found:
        print(f"FAIL: {len(found)} include(s) against the layers of docs/architecture.md")
        return 1
    print(f"ok: {seen} cross-layer includes, all downwards")
    return 0


if __name__ == "__main__":
    sys.exit(main())
