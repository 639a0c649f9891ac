# Sphinx configuration of csympnet's documentation site: the user guide (the Markdown files in
# docs/, read by MyST) and the Python API reference, generated from the docstrings of the
# importable package. Built by `make docs` into build/docs/html.
import os
import sys

import csympnet  # the build's package: PYTHONPATH=build/python (make docs sets it)

project = "csympnet"
author = "the csympnet authors"
copyright = "2026, the csympnet authors"
release = csympnet.__version__
version = release

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.mathjax",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 3
autodoc_member_order = "bysource"
autodoc_typehints = "none"
# Links from the guide to source files of the repository are not pages of the site.
suppress_warnings = ["myst.xref_missing"]


# The docstrings are written as plain text, for help() and editors, not as reStructuredText.
# Each is shown as its first paragraph in prose (escaped) and the rest verbatim, as the author
# laid it out, so that no docstring is misread as markup (an underscore as a link, |x| as a
# substitution, an indented continuation as a quote).
_RST_SPECIAL = "\\*`|_[]<>:"


def _escape(text):
    return "".join("\\" + c if c in _RST_SPECIAL else c for c in text)


def _plain_text_docstring(app, what, name, obj, options, lines):
    if not lines:
        return
    end = next((i for i, line in enumerate(lines) if not line.strip()), len(lines))
    summary = " ".join(line.strip() for line in lines[:end])
    rest = lines[end + 1:]
    while rest and not rest[-1].strip():
        rest.pop()
    out = [_escape(summary), ""]
    if any(line.strip() for line in rest):
        out += ["::", ""] + ["    " + line for line in rest] + [""]
    lines[:] = out


def setup(app):
    app.connect("autodoc-process-docstring", _plain_text_docstring)


html_theme = "alabaster"
html_theme_options = {"description": "Conformally symplectic networks for damped systems",
                      "fixed_sidebar": True}
html_static_path = []
exclude_patterns = ["_build"]
