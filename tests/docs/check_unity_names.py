#!/usr/bin/env python3
"""The build compiles each folder's files up to 8 at a time as one unity file
(CSYMPNET_UNITY, docs/architecture.md, "Packaging"). Two files of a folder that each define a
local helper of one name then stop the build where their parameters are the same, and where
they differ a call may silently find the other file's overload. A local helper named like a
function or type of a header that the folder includes is hidden the same way.

Checks that every name a file defines at namespace scope inside an anonymous namespace (or as
`static`) is defined by no other file of its folder, and by no header of tests/support or of
the folder itself; and that the checker sees something: planted clashes must be caught.

Usage: check_unity_names.py [REPO]   (exit 0 when every local name is unique; else each clash)
"""
import os
import re
import sys
import tempfile

# A definition or declaration that starts at column 0 (clang-format's layout): a function, a
# variable or constant, or a type. Group 1 is its name.
DEFINITION = re.compile(
    r"^(?:template\s*<[^>]*>\s*)?(?:(?:static|inline|constexpr|const|extern)\s+)*"
    r"[A-Za-z_][\w:<>,\s*&]*?[\s*&]([A-Za-z_]\w*)\s*(?:\(|=|\[|\{|;)")
TYPE = re.compile(r"^(?:struct|class|enum class|enum|union)\s+([A-Za-z_]\w*)")
ALIAS = re.compile(r"^using\s+([A-Za-z_]\w*)\s*=")
# Overloads chosen by their argument's own type (ADL hooks, GoogleTest's printers): distinct
# types never clash.
BY_TYPE = {"PrintTo", "to_json", "from_json", "operator", "main"}
UNITY_FOLDERS = ("src", "apps", os.path.join("python", "src"), "tests")
OUTSIDE = {os.path.join("src", "kernels"), os.path.join("tests", "support"),
           os.path.join("tests", "docs")}


def names(path, local_only):
    """Names defined at column 0; with local_only, those inside `namespace {` or `static`."""
    found, depth_anon = set(), 0
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.startswith("namespace {"):
                depth_anon += 1
                continue
            if line.startswith("}  // namespace") and depth_anon and "namespace " not in line[15:]:
                depth_anon -= 1
                continue
            if not line or line[0] in " \t#/}" or line.startswith(("namespace", "TEST", "INSTANTIATE",
                                                                  "using namespace")):
                continue
            local = depth_anon > 0 or line.startswith("static ")
            if local_only and not local:
                continue
            m = TYPE.match(line) or ALIAS.match(line) or DEFINITION.match(line)
            if m and m.group(1) not in BY_TYPE:
                found.add(m.group(1))
    return found


def folders(repo):
    for top in UNITY_FOLDERS:
        for dirpath, _, files in os.walk(os.path.join(repo, top)):
            rel = os.path.relpath(dirpath, repo)
            if rel in OUTSIDE or not any(n.endswith(".cpp") for n in files):
                continue
            yield dirpath, sorted(files)


def clashes(repo):
    shared = {}
    support = os.path.join(repo, "tests", "support")
    for name in sorted(os.listdir(support)) if os.path.isdir(support) else []:
        if name.endswith(".hpp"):
            for n in names(os.path.join(support, name), local_only=False):
                shared.setdefault(n, os.path.join("tests", "support", name))
    out = []
    for dirpath, files in folders(repo):
        headers = dict(shared)
        for name in files:
            if name.endswith(".hpp"):
                for n in names(os.path.join(dirpath, name), local_only=False):
                    headers.setdefault(n, os.path.relpath(os.path.join(dirpath, name), repo))
        owner = {}
        for name in files:
            if not name.endswith(".cpp"):
                continue
            rel = os.path.relpath(os.path.join(dirpath, name), repo)
            for n in sorted(names(os.path.join(dirpath, name), local_only=True)):
                if n in owner:
                    out.append(f"{rel}: '{n}' is also local to {owner[n]}")
                elif n in headers:
                    out.append(f"{rel}: '{n}' is also defined in {headers[n]}")
                owner.setdefault(n, rel)
    return out


def self_test():
    """Planted clashes are caught; distinct names and by-type overloads are not."""
    with tempfile.TemporaryDirectory() as repo:
        layer = os.path.join(repo, "src", "layer")
        support = os.path.join(repo, "tests", "support")
        os.makedirs(layer)
        os.makedirs(support)
        files = {
            os.path.join(layer, "a.cpp"): "namespace x {\nnamespace {\nint helper(int v) {\n"
            "  return v;\n}\nvoid to_json(int&, const A&);\nconstexpr int kOnly = 1;\n}  // namespace\n}"
            "  // namespace x\n",
            os.path.join(layer, "b.cpp"): "namespace x {\nnamespace {\ndouble helper(double v) {\n"
            "  return v;\n}\nvoid to_json(int&, const B&);\nstruct same_bits {};\n}  // namespace\n}"
            "  // namespace x\nstatic int counter = 0;\n",
            os.path.join(layer, "c.cpp"): "namespace x {\nint counter = 0;\n}  // namespace x\n",
            os.path.join(support, "same_bits.hpp"): "inline bool same_bits(double a, double b);\n",
        }
        for path, text in files.items():
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
        found = clashes(repo)
        expected = ["src/layer/b.cpp: 'helper' is also local to src/layer/a.cpp",
                    "src/layer/b.cpp: 'same_bits' is also defined in tests/support/same_bits.hpp"]
        if found != expected:
            sys.exit(f"check_unity_names.py: the self-test found {found}, expected {expected}")


def main():
    repo = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..")
    self_test()
    found = clashes(repo)
    for line in found:
        print(line)
    if found:
        print(f"{len(found)} local names clash within a unity folder: rename them, or move a "
              "shared helper into a header (docs/architecture.md, \"Packaging\")")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
