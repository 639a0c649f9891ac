#!/usr/bin/env python3
"""Two builds of csympnet side by side on the records of an identification benchmark run: each
record fitted by both, alternately, in one run, so that the machine's drift between runs (on a
shared machine, 10-25% from one benchmark run to the next) does not enter the ratio
(docs/benchmarks.md).

    /usr/bin/python3 experiments/fit_cost_ab.py --results R/results.json --before B --after A
        --out DIR [--max-d 3] [--every 4] [--rounds 2]

--results: a results.json of experiments/identification_benchmark.py (its cases' data files
are fitted again); --before, --after: the two csympnet binaries; --out: an empty or new
directory for the fits. The records with d <= --max-d, sorted by the CPU seconds the run
recorded, every --every-th of them (spread over the distribution). Each round fits every
record with both builds, the order alternating between rounds; a record's time is its fastest
round. Printed: per build the sum and median of the records' CPU seconds (user + system, from
wait4), the per-record ratio after / before (median and range), and how many records kept
gamma_hat, its interval and the verdict to the bit. One fit at a time: run nothing else meanwhile.
"""
import argparse
import json
import os
import resource
import statistics
import subprocess
import sys


def cpu_of_children():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def fit(binary, data, out):
    """One `csympnet fit`; returns (CPU seconds, (gamma_hat, low, high) or None)."""
    before = cpu_of_children()
    done = subprocess.run([binary, "fit", data, "--out", out, "-q", "--no-figures"],
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    seconds = cpu_of_children() - before
    # A fit that ends "not identified" exits non-zero and still writes its report.
    answer = None
    report = os.path.join(out, "report.json")
    if os.path.isfile(report):
        with open(report) as f:
            rep = json.load(f)
        answer = (rep.get("gamma_hat"), rep.get("gamma_ci_low"), rep.get("gamma_ci_high"),
                  rep.get("verdict"))
    elif done.returncode != 0:
        print(f"  {binary} fit {data}: exit status {done.returncode}, no report", flush=True)
    return seconds, answer


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--results", required=True)
    ap.add_argument("--before", required=True)
    ap.add_argument("--after", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--max-d", type=int, default=3)
    ap.add_argument("--every", type=int, default=4)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args()
    for name in ("before", "after"):
        path = getattr(args, name)
        if not (os.path.isfile(path) and os.access(path, os.X_OK)):
            sys.exit(f"--{name} {path}: expected an executable csympnet binary")
    if args.every < 1 or args.rounds < 1:
        sys.exit("--every and --rounds: expected integers >= 1")
    try:
        with open(args.results) as f:
            run = json.load(f)
        cases = run["cases"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        sys.exit(f"--results {args.results}: expected a results.json of the identification "
                 f"benchmark ({e})")
    if os.path.exists(args.out) and os.listdir(args.out):
        sys.exit(f"--out {args.out}: expected an empty or new directory")
    base = os.path.dirname(os.path.abspath(args.results))
    chosen = []
    for c in cases:
        m = c.get("methods", {}).get("csympnet", {})
        if c.get("d", 0) <= args.max_d and m.get("cpu_seconds") is not None:
            chosen.append((m["cpu_seconds"], c["id"]))
    chosen.sort()
    ids = [i for _, i in chosen[::args.every]]
    if not ids:
        sys.exit(f"--results {args.results}: no record with d <= {args.max_d} and a csympnet time")
    builds = {"before": args.before, "after": args.after}
    times = {b: {i: [] for i in ids} for b in builds}
    answers = {b: {} for b in builds}
    for r in range(args.rounds):
        order = ["before", "after"] if r % 2 == 0 else ["after", "before"]
        for i in ids:
            data = os.path.join(base, "cases", i, "data.csv")
            for b in order:
                out = os.path.join(args.out, b, f"{i}-{r}")
                seconds, answer = fit(builds[b], data, out)
                times[b][i].append(seconds)
                answers[b][i] = answer
            print(f"[round {r + 1}] {i}: before {times['before'][i][-1]:.2f} s, "
                  f"after {times['after'][i][-1]:.2f} s", flush=True)
    best = {b: {i: min(times[b][i]) for i in ids} for b in builds}
    print(f"\n{len(ids)} records (of the {len(chosen)} with d <= {args.max_d} sorted by CPU s, "
          f"one in {args.every} from the fastest), {args.rounds} rounds, the fastest of each:")
    for b in builds:
        v = list(best[b].values())
        print(f"  {b}: {builds[b]}: CPU s summed {sum(v):.2f}, median {statistics.median(v):.3f}")
    ratios = [best["after"][i] / best["before"][i] for i in ids if best["before"][i] > 0]
    print(f"  per-record ratio after / before: median {statistics.median(ratios):.3f} "
          f"[{min(ratios):.3f}, {max(ratios):.3f}]")
    same = sum(1 for i in ids if answers["before"][i] is not None
               and answers["before"][i] == answers["after"][i])
    print(f"  gamma_hat, its interval and the verdict the same bits: {same} of {len(ids)}")


if __name__ == "__main__":
    main()
