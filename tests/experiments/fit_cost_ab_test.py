"""experiments/fit_cost_ab.py with two stand-ins for csympnet (small Python scripts that write a
report): the records chosen (d and every k-th by CPU s), both builds run on each, the count of
answers that kept their bits (a "not identified" report, exit status non-zero, included), and
the refusals of a bad results file, a binary that is not executable and an output directory
in use."""
import json
import os
import stat
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
SCRIPT = os.path.join(HERE, "..", "..", "experiments", "fit_cost_ab.py")

# A stand-in for `csympnet fit DATA --out OUT -q --no-figures`: gamma_hat from the data file's
# first line (times `scale`), verdict "not identified" (exit 3) where the line says so.
STAND_IN = """#!{python}
import json, os, sys
args = sys.argv[1:]
assert args[0] == "fit" and "--out" in args and "-q" in args and "--no-figures" in args
data, out = args[1], args[args.index("--out") + 1]
line = open(data).read().split()[0]
os.makedirs(out)
if line == "none":
    rep = {{"gamma_hat": None, "gamma_ci_low": None, "gamma_ci_high": None,
           "verdict": "not identified"}}
else:
    g = float(line) * {scale}
    rep = {{"gamma_hat": g, "gamma_ci_low": 0.9 * g, "gamma_ci_high": 1.1 * g,
           "verdict": "identified"}}
json.dump(rep, open(os.path.join(out, "report.json"), "w"))
sys.exit(3 if line == "none" else 0)
"""


def stand_in(d, name, scale):
    path = os.path.join(d, name)
    with open(path, "w") as f:
        f.write(STAND_IN.format(python=sys.executable, scale=scale))
    os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR)
    return path


def benchmark_run(d):
    """A results.json of four records (one at d = 5) and their data files."""
    cases = []
    for i, (dim, cpu, line) in enumerate([(1, 3.0, "0.5"), (2, 1.0, "0.25"), (5, 2.0, "1.0"),
                                          (3, 2.5, "none")]):
        cid = f"c{i:03d}"
        os.makedirs(os.path.join(d, "run", "cases", cid))
        with open(os.path.join(d, "run", "cases", cid, "data.csv"), "w") as f:
            f.write(line + "\n")
        cases.append({"id": cid, "d": dim, "methods": {"csympnet": {"cpu_seconds": cpu}}})
    path = os.path.join(d, "run", "results.json")
    with open(path, "w") as f:
        json.dump({"cases": cases}, f)
    return path


def ab(results, before, after, out, *extra):
    return subprocess.run([sys.executable, SCRIPT, "--results", results, "--before", before,
                           "--after", after, "--out", out, *extra],
                          capture_output=True, text=True, timeout=120)


def test_chooses_records_runs_both_and_compares_answers():
    with tempfile.TemporaryDirectory() as d:
        results = benchmark_run(d)
        same, other = stand_in(d, "same", 1.0), stand_in(d, "other", 2.0)
        ok = ab(results, same, same, os.path.join(d, "o1"), "--rounds", "2", "--every", "1")
        assert ok.returncode == 0, ok.stderr
        # d <= 3: c001 (1.0 s), c003 (2.5 s), c000 (3.0 s); c002 (d = 5) left out.
        assert "3 records (of the 3 with d <= 3 sorted by CPU s, one in 1 from the fastest), " \
            "2 rounds" in ok.stdout, ok.stdout
        assert "c002" not in ok.stdout
        assert "the same bits: 3 of 3" in ok.stdout, ok.stdout
        assert sorted(os.listdir(os.path.join(d, "o1", "after"))) == [
            "c000-0", "c000-1", "c001-0", "c001-1", "c003-0", "c003-1"]
        # The other build moves the two identified answers; "not identified" stays.
        moved = ab(results, same, other, os.path.join(d, "o2"), "--rounds", "1", "--every", "1")
        assert moved.returncode == 0, moved.stderr
        assert "the same bits: 1 of 3" in moved.stdout, moved.stdout
        # Every 2nd by CPU s: c001 and c000.
        thin = ab(results, same, same, os.path.join(d, "o3"), "--rounds", "1", "--every", "2")
        assert "2 records" in thin.stdout and "c003" not in thin.stdout, thin.stdout


def test_refuses_bad_input():
    with tempfile.TemporaryDirectory() as d:
        results = benchmark_run(d)
        same = stand_in(d, "same", 1.0)
        bad = os.path.join(d, "bad.json")
        with open(bad, "w") as f:
            f.write("[1, 2")
        r = ab(bad, same, same, os.path.join(d, "o"))
        assert r.returncode != 0 and "--results" in r.stderr, r.stderr
        r = ab(results, os.path.join(d, "missing"), same, os.path.join(d, "o"))
        assert r.returncode != 0 and "--before" in r.stderr, r.stderr
        used = os.path.join(d, "used")
        os.makedirs(used)
        open(os.path.join(used, "keep.txt"), "w").close()
        r = ab(results, same, same, used)
        assert r.returncode != 0 and "--out" in r.stderr, r.stderr
        assert os.listdir(used) == ["keep.txt"]
        r = ab(results, same, same, os.path.join(d, "o"), "--every", "0")
        assert r.returncode != 0 and "--every" in r.stderr, r.stderr


if __name__ == "__main__":
    sys.path.insert(0, HERE)
    from script_tests import run
    run(globals())
