#!/usr/bin/env python3
"""Runs the Python blocks of the documentation and checks the output they claim.

    check_doc_blocks.py --source ROOT --work DIR [FILE.md...]   (default: README.md docs/*.md)

A Markdown file opts in with the line `<!-- docs-test: run -->`. Its ```python blocks then run
in order, in one namespace, in DIR (where `examples` and `experiments` link to ROOT's), as a
reader pasting them into one session would run them. A block whose first line starts with
`# not run by make test:` is skipped (the rest of that line says why, visibly). A fence with no
language (or `text`) directly after a python or sh block is the output that block claims: what
the block prints must match it, text exactly (runs of spaces aside) and every number to the
digits the text shows (0.12037 matches a printed 0.120371, not 0.12041). An sh block runs (bash,
in DIR, with the directory of $CSYMPNET_CLI first on PATH) only when it claims an output.

In a file that has not opted in, a block followed by such an output block is an error: every
block that claims an output is run.
"""

import argparse
import contextlib
import glob
import io
import os
import re
import subprocess
import sys
import time
import traceback

OPT_IN = "<!-- docs-test: run -->"
SKIP = "# not run by make test:"
NUMBER = re.compile(r"[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def blocks(path):
    """(line, language, text) of each fenced block, in order."""
    lines = open(path, encoding="utf-8").read().split("\n")
    out, i = [], 0
    while i < len(lines):
        m = re.match(r"^\s*```(\S*)\s*$", lines[i])
        if not m:
            i += 1
            continue
        j = i + 1
        while j < len(lines) and not re.match(r"^\s*```\s*$", lines[j]):
            j += 1
        out.append({"line": i + 1, "end": j + 1, "lang": m.group(1), "text": "\n".join(lines[i + 1:j])})
        i = j + 1
    # Each python block's claimed output: the next block, if it is plain and only blank lines
    # separate the two.
    for k, b in enumerate(out):
        b["claims"] = None
        if b["lang"] in ("python", "sh") and k + 1 < len(out):
            nxt = out[k + 1]
            between = lines[b["end"]:nxt["line"] - 1]
            if nxt["lang"] in ("", "text") and not any(s.strip() for s in between):
                b["claims"] = nxt
    return out


def decimals(token):
    """Digits after the point in a number's mantissa, and its exponent."""
    mantissa, _, exponent = token.lower().partition("e")
    places = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return places, int(exponent) if exponent else 0


def matches(expected, actual):
    """None when `actual` shows `expected` to the digits `expected` shows, else why not."""
    e_text, a_text = NUMBER.split(expected), NUMBER.split(actual)
    e_nums, a_nums = NUMBER.findall(expected), NUMBER.findall(actual)
    norm = [" ".join(s.split()) for s in e_text], [" ".join(s.split()) for s in a_text]
    if norm[0] != norm[1] or len(e_nums) != len(a_nums):
        return "the text differs"
    for e, a in zip(e_nums, a_nums):
        places, exponent = decimals(e)
        scale = 10.0 ** (exponent - places)
        if abs(float(a) - float(e)) > 0.5 * scale * (1 + 1e-9):
            return f"{a} printed where the text shows {e}"
    return None


def run_file(path, work):
    text = open(path, encoding="utf-8").read()
    failures, ran, skipped = [], 0, 0
    found = blocks(path)
    if OPT_IN not in text:
        for b in found:
            if b["claims"] is not None:
                failures.append(f"{path}:{b['line']}: a {b['lang']} block claims an output (line "
                                f"{b['claims']['line']}) but the file is not run: add {OPT_IN}")
        return failures, ran, skipped
    namespace = {"__name__": "__main__"}
    for b in found:
        if b["lang"] not in ("python", "sh") or (b["lang"] == "sh" and b["claims"] is None):
            continue
        if b["text"].lstrip().startswith(SKIP):
            skipped += 1
            continue
        out = io.StringIO()
        t0 = time.monotonic()
        if b["lang"] == "sh":
            env = dict(os.environ)
            cli = env.get("CSYMPNET_CLI")
            if cli:
                env["PATH"] = os.path.dirname(os.path.abspath(cli)) + os.pathsep + env["PATH"]
            p = subprocess.run(["bash", "-e", "-c", b["text"]], env=env, capture_output=True,
                               text=True)
            if p.returncode != 0:
                failures.append(f"{path}:{b['line']}: the block exited with {p.returncode}\n"
                                f"{p.stderr}")
                continue
            out.write(p.stdout)
        else:
            try:
                with contextlib.redirect_stdout(out):
                    exec(compile(b["text"], f"{path}:{b['line']}", "exec"), namespace)
            except Exception:
                failures.append(f"{path}:{b['line']}: the block raised\n{traceback.format_exc()}")
                break
        ran += 1
        printed = out.getvalue().strip()
        print(f"{path}:{b['line']}: ran in {time.monotonic() - t0:.1f} s", file=sys.stderr)
        if b["claims"] is not None:
            claimed = b["claims"]["text"].strip()
            why = matches(claimed, printed)
            if why:
                failures.append(f"{path}:{b['line']}: {why}\n  the text shows:\n    "
                                + claimed.replace("\n", "\n    ") + "\n  the block printed:\n    "
                                + printed.replace("\n", "\n    "))
    return failures, ran, skipped


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--source", required=True, help="the repository's root")
    ap.add_argument("--work", required=True, help="scratch directory the blocks run in")
    ap.add_argument("files", nargs="*", help="relative to ROOT (default: README.md docs/*.md)")
    args = ap.parse_args()
    source = os.path.abspath(args.source)
    files = [os.path.join(source, f) for f in args.files] or (
        [os.path.join(source, "README.md")]
        + sorted(glob.glob(os.path.join(source, "docs", "*.md"))))
    os.makedirs(args.work, exist_ok=True)
    for name in ("examples", "experiments"):
        link = os.path.join(args.work, name)
        if not os.path.lexists(link):
            os.symlink(os.path.join(source, name), link)
    os.chdir(args.work)
    failures = []
    for f in files:
        fails, ran, skipped = run_file(f, args.work)
        print(f"{os.path.relpath(f, source)}: {ran} blocks run, {skipped} skipped", file=sys.stderr)
        failures += fails
    for f in failures:
        print("FAIL " + f, file=sys.stderr)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
