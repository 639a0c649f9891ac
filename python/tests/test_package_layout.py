"""The package's shape: its modules import one another without a circle (docs/architecture.md,
"Python module", draws the graph), and no function is too long to read. A circle makes what a
module holds at import time depend on which module was imported first; the imports inside
functions count too, since they close the same circle later."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "csympnet"


def package_imports(path):
    """The package modules that the file at `path` imports, at any depth of its code."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom):
            if node.level == 1 and node.module:  # from ._x import y
                found.add(node.module.split(".")[0])
            elif node.level == 1:  # from . import _x, _y
                found.update(alias.name for alias in node.names)
            elif node.level == 0 and node.module and node.module.split(".")[0] == "csympnet":
                parts = node.module.split(".")
                found.update([parts[1]] if len(parts) > 1 else [a.name for a in node.names])
        elif isinstance(node, ast.Import):  # import csympnet.torch
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == "csympnet" and len(parts) > 1:
                    found.add(parts[1])
    # _core is the compiled module: it imports nothing of the package.
    return {name for name in found if (PACKAGE / f"{name}.py").exists()}


def import_graph():
    return {path.stem: package_imports(path) for path in sorted(PACKAGE.glob("*.py"))}


def find_circle(graph):
    """One circle of the graph as a list of modules (first == last), or None."""
    state = {}  # absent: not seen; 1: on the current path; 2: done

    def visit(node, path):
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            if nxt not in state:
                circle = visit(nxt, path + [nxt])
                if circle:
                    return circle
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state:
            circle = visit(start, [start])
            if circle:
                return circle
    return None


def test_the_finder_finds_a_planted_circle():
    assert find_circle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_circle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_no_module_of_the_package_imports_itself_back():
    graph = import_graph()
    assert "_records" in graph and "_identify" in graph
    circle = find_circle(graph)
    assert circle is None, "import circle: " + " -> ".join(circle)


def test_imports_inside_functions_are_seen():
    graph = import_graph()
    # _fit_record loads a model inside a function (the compiled module only when needed), and
    # plot, which loads by path too, imports _fit_record by its absolute name inside one.
    assert "_model" in graph["_fit_record"]
    assert "_fit_record" in graph["plot"]


def drawn_order():
    """The modules of docs/architecture.md's list ("Python module"), top to bottom: each line
    starts with one module, or names several that import no module of the package."""
    text = (PACKAGE.parents[1] / "docs" / "architecture.md").read_text(encoding="utf-8")
    block = text[text.index("## Python module"):]
    block = block[block.index("```text") + len("```text"):]
    block = block[:block.index("```")]
    rows = []
    for line in block.strip().splitlines():
        if "," in line.split("  ")[0]:
            rows.append([name.strip().split()[0] for name in line.split(",")])
        else:
            rows.append([line.split()[0]])
    return rows


def test_the_drawn_graph_is_the_packages():
    """Each module of the list imports only modules below it, and every module is listed."""
    graph = import_graph()
    rows = drawn_order()
    listed = [name for row in rows for name in row]
    assert set(graph) <= set(listed), set(graph) - set(listed)
    for k, row in enumerate(rows):
        below = {name for later in rows[k + 1:] for name in later}
        for name in row:
            assert graph.get(name, set()) <= below, (name, graph[name] - below)


def test_the_users_records_are_read_in_one_module():
    """Only _records reads trajectories and pairs: the entries import it, and it imports no
    entry back."""
    graph = import_graph()
    for entry in ("_identify", "_estimator", "_fit", "_model", "_data"):
        assert "_records" in graph[entry] or "_records" in set().union(
            *(graph[m] for m in graph[entry])), entry
    assert graph["_records"] <= {"_checks", "_frames"}


# A function longer than this is stages waiting for names (docstrings included).
MAX_FUNCTION_LINES = 150


def test_no_function_of_the_package_is_longer_than_150_lines():
    long = []
    for path in sorted(PACKAGE.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > MAX_FUNCTION_LINES:
                    long.append(f"{path.name}:{node.lineno} {node.name} ({lines} lines)")
    assert not long, long
