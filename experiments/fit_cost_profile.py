#!/usr/bin/env python3
"""Where `csympnet fit`'s time goes, per stage, over an identification benchmark's records.

Reads the results.json that experiments/identification_benchmark.py writes (any plan run with a
csympnet whose fits write "by_stage" in timings.json) and prints, per csympnet variant
(csympnet, csympnet_positions, csympnet_differenced, ...):
  - the number of fits and their median, 90th percentile and largest CPU seconds (wait4), beside
    the oracle's median CPU seconds when the plan ran it;
  - each stage family's share of all the fits' CPU seconds, and in how many fits it ran.
Stages are grouped into families: the library candidates ("library: ..."), the neural cores'
AdamW and LM ("AdamW (core i of n, ...)", "LM (core i of n, ...)"), and every other stage by
its name.

  /usr/bin/python3 experiments/fit_cost_profile.py --results D/results.json [--markdown]
"""
import argparse
import json
import re
import statistics
import sys


def family(stage):
    """the family a stage name belongs to"""
    if stage.startswith("library:"):
        return "library candidates"
    m = re.match(r"^(AdamW|LM) \(core \d+ of \d+", stage)
    if m:
        return f"{m.group(1)}, neural cores"
    return stage


def quantile(xs, q):
    xs = sorted(xs)
    if not xs:
        return float("nan")
    k = min(len(xs) - 1, max(0, int(round(q * (len(xs) - 1)))))
    return xs[k]


def profile(cases):
    """{variant: {"cpu": [...], "families": {family: [cpu seconds, fits]}}}, oracle CPU list"""
    out, oracle = {}, []
    for c in cases:
        methods = c.get("methods") or {}
        o = methods.get("oracle") or {}
        if isinstance(o.get("cpu_seconds"), (int, float)):
            oracle.append(o["cpu_seconds"])
        for name, r in methods.items():
            if not name.startswith("csympnet") or not isinstance(r, dict):
                continue
            stages = r.get("stage_cpu_seconds")
            cpu = r.get("cpu_seconds")
            if not isinstance(stages, dict) or not isinstance(cpu, (int, float)):
                continue
            v = out.setdefault(name, {"cpu": [], "families": {}})
            v["cpu"].append(cpu)
            seen = set()
            for stage, s in stages.items():
                if not isinstance(s, (int, float)):
                    continue
                f = family(stage)
                acc = v["families"].setdefault(f, [0.0, 0])
                acc[0] += s
                if f not in seen:
                    acc[1] += 1
                    seen.add(f)
    return out, oracle


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", required=True, help="a benchmark's results.json")
    ap.add_argument("--top", type=int, default=8, help="stage families listed per variant")
    args = ap.parse_args(argv)
    try:
        with open(args.results) as f:
            doc = json.load(f)
    except (OSError, ValueError) as e:
        sys.exit(f"{args.results}: cannot read a benchmark's results ({e})")
    cases = doc.get("cases") if isinstance(doc, dict) else None
    if not isinstance(cases, list):
        sys.exit(f"{args.results}: expected an object with a \"cases\" list")
    variants, oracle = profile(cases)
    if not variants:
        sys.exit(f"{args.results}: no csympnet fit with per-stage timings (timings.json "
                 "\"by_stage\") and CPU seconds")
    if oracle:
        print(f"oracle: {len(oracle)} fits, median {statistics.median(oracle):.2f} CPU s")
    for name, v in sorted(variants.items()):
        cpu = v["cpu"]
        total = sum(cpu)
        print(f"\n{name}: {len(cpu)} fits, CPU s median {statistics.median(cpu):.2f}, "
              f"90th percentile {quantile(cpu, 0.9):.2f}, largest {max(cpu):.2f}")
        print("| stage family | share of CPU s | fits it ran in |")
        print("|---|---|---|")
        fams = sorted(v["families"].items(), key=lambda kv: -kv[1][0])
        for f, (s, n) in fams[:args.top]:
            print(f"| {f} | {100.0 * s / total:.0f}% | {n} |")


if __name__ == "__main__":
    main()
