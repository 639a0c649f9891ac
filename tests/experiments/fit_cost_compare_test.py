"""experiments/fit_cost_compare.py on two small hand-made runs: the sums, the per-record ratios,
the records whose answer kept its bits, the coverage counts, the records left out with --skip,
and the refusal of runs that share no record."""
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
EXPERIMENTS = os.path.join(HERE, "..", "..", "experiments")
sys.path.insert(0, EXPERIMENTS)

import fit_cost_compare as fcc  # noqa: E402


def fit(cpu, gamma, low, high, covers=True, status="ok", rel_err=1e-3):
    return {"status": status, "cpu_seconds": cpu, "gamma_hat": gamma, "ci_low": low,
            "ci_high": high, "covers": covers, "rel_err": rel_err}


def runs():
    before = {"cases": [
        {"id": "c0", "methods": {"csympnet": fit(10.0, 1.0, 0.9, 1.1)}},
        {"id": "c1", "methods": {"csympnet": fit(4.0, 2.0, 1.9, 2.1, covers=False)}},
        {"id": "c2", "methods": {"csympnet": fit(6.0, None, None, None, status="not_identified")},
         }]}
    after = {"cases": [
        {"id": "c0", "methods": {"csympnet": fit(5.0, 1.0, 0.9, 1.1)}},
        {"id": "c1", "methods": {"csympnet": fit(1.0, 2.0000001, 1.9, 2.1, covers=True)}},
        {"id": "c2", "methods": {"csympnet": fit(3.0, None, None, None, status="not_identified")},
         }]}
    return before, after


def test_sums_ratios_answers_and_coverage():
    before, after = runs()
    with tempfile.TemporaryDirectory() as d:
        for name, run in (("b.json", before), ("a.json", after)):
            with open(os.path.join(d, name), "w") as f:
                json.dump(run, f)
        b, a = fcc.load(os.path.join(d, "b.json")), fcc.load(os.path.join(d, "a.json"))
    o = fcc.compare(b, a, "csympnet", set())
    assert o["records"] == 3 and o["timed"] == 3
    assert abs(o["cpu_before"] - 20.0) < 1e-12 and abs(o["cpu_after"] - 9.0) < 1e-12
    assert abs(o["sum_ratio"] - 0.45) < 1e-12
    assert abs(o["median_ratio"] - 0.5) < 1e-12  # ratios 0.5, 0.25, 0.5
    assert abs(o["min_ratio"] - 0.25) < 1e-12 and abs(o["max_ratio"] - 0.5) < 1e-12
    # c0 kept its bits, c2 stayed not identified, c1's gamma moved.
    assert o["same_answer"] == 2 and o["changed"] == ["c1"]
    assert o["identified_before"] == 2 and o["identified_after"] == 2
    assert o["covered_before"] == 1 and o["covered_after"] == 2
    skipped = fcc.compare(b, a, "csympnet", {"c1"})
    assert skipped["records"] == 2 and abs(skipped["cpu_before"] - 16.0) < 1e-12


def test_runs_from_the_command_line_and_refuses_unrelated_runs():
    before, after = runs()
    with tempfile.TemporaryDirectory() as d:
        pb, pa, other = (os.path.join(d, n) for n in ("b.json", "a.json", "o.json"))
        for path, run in ((pb, before), (pa, after),
                          (other, {"cases": [{"id": "x9", "methods": {}}]})):
            with open(path, "w") as f:
                json.dump(run, f)
        script = os.path.join(EXPERIMENTS, "fit_cost_compare.py")
        ok = subprocess.run([sys.executable, script, "--before", pb, "--after", pa],
                            capture_output=True, text=True, timeout=60)
        assert ok.returncode == 0, ok.stderr
        assert "| csympnet | 3 | 20.0 -> 9.0 (0.45) |" in ok.stdout, ok.stdout
        assert "answer changed on c1" in ok.stderr
        bad = subprocess.run([sys.executable, script, "--before", pb, "--after", other],
                             capture_output=True, text=True, timeout=60)
        assert bad.returncode != 0 and "share no record" in bad.stderr


if __name__ == "__main__":
    from script_tests import run
    run(globals())
