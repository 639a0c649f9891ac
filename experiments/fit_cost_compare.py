#!/usr/bin/env python3
"""Two identification benchmark runs of the same plan side by side: what a change of csympnet
did to each fit's cost and answer (docs/benchmarks.md, "A fit's cost").

    /usr/bin/python3 experiments/fit_cost_compare.py --before B/results.json --after A/results.json
        [--skip ID,ID]

Both runs must hold the same records (the same plan, cases and seed; their ids are matched).
Per csympnet variant (csympnet, csympnet_positions, csympnet_differenced, ...), over the
records both fitted with CPU seconds (wait4 of `fit`; --skip leaves records out of the sums,
e.g. ones a build ran beside):
  - the CPU seconds summed before and after, their ratio, and the median and range of the
    per-record ratios;
  - how many records kept gamma_hat and its interval to the bit;
  - how many were identified and covered the truth, before and after, and the median relative
    error of gamma_hat over the identified ones.
"""
import argparse
import json
import statistics
import sys


def load(path):
    with open(path) as f:
        data = json.load(f)
    cases = data.get("cases") if isinstance(data, dict) else data
    if not isinstance(cases, list):
        sys.exit(f"{path}: expected a results.json of the identification benchmark (a list of "
                 f"cases, or an object with 'cases')")
    return {c["id"]: c for c in cases if isinstance(c, dict) and "id" in c}


def variants(cases):
    out = set()
    for c in cases.values():
        for name in (c.get("methods") or {}):
            if name.startswith("csympnet"):
                out.add(name)
    return sorted(out)


def answer(r):
    """gamma_hat and its interval, or None"""
    if not isinstance(r, dict) or r.get("status") != "ok":
        return None
    return (r.get("gamma_hat"), r.get("ci_low"), r.get("ci_high"))


def compare(before, after, name, skip):
    ids = [i for i in sorted(before) if i in after and i not in skip]
    rows = []
    for i in ids:
        b = (before[i].get("methods") or {}).get(name)
        a = (after[i].get("methods") or {}).get(name)
        if not isinstance(b, dict) or not isinstance(a, dict):
            continue
        rows.append((i, b, a))
    timed = [(i, b["cpu_seconds"], a["cpu_seconds"]) for i, b, a in rows
             if isinstance(b.get("cpu_seconds"), (int, float))
             and isinstance(a.get("cpu_seconds"), (int, float)) and b["cpu_seconds"] > 0]
    out = {"variant": name, "records": len(rows), "timed": len(timed)}
    if timed:
        sb = sum(t[1] for t in timed)
        sa = sum(t[2] for t in timed)
        ratios = [t[2] / t[1] for t in timed]
        out.update(cpu_before=sb, cpu_after=sa, sum_ratio=sa / sb,
                   median_ratio=statistics.median(ratios), min_ratio=min(ratios),
                   max_ratio=max(ratios),
                   median_cpu_before=statistics.median(t[1] for t in timed),
                   median_cpu_after=statistics.median(t[2] for t in timed))
    out["same_answer"] = sum(1 for _, b, a in rows if answer(b) is not None and answer(b) == answer(a)
                             or answer(b) is None and answer(a) is None
                             and b.get("status") == a.get("status"))
    for tag, k in (("before", 1), ("after", 2)):
        rs = [row[k] for row in rows]
        ok = [r for r in rs if r.get("status") == "ok"]
        out[f"identified_{tag}"] = len(ok)
        out[f"covered_{tag}"] = sum(1 for r in ok if r.get("covers") is True)
        errs = [r["rel_err"] for r in ok if isinstance(r.get("rel_err"), (int, float))]
        out[f"median_rel_err_{tag}"] = statistics.median(errs) if errs else None
    out["changed"] = [i for i, b, a in rows if answer(b) != answer(a)
                      or b.get("status") != a.get("status")]
    return out


def fmt(x, spec):
    return "-" if x is None else format(x, spec)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--before", required=True, help="results.json of the run before the change")
    ap.add_argument("--after", required=True, help="results.json of the run after it")
    ap.add_argument("--skip", default="", help="comma-separated record ids left out")
    args = ap.parse_args(argv)
    before, after = load(args.before), load(args.after)
    skip = {s for s in args.skip.split(",") if s}
    common = set(before) & set(after)
    if not common:
        sys.exit("the two runs share no record ids: are they the same plan, cases and seed?")
    print("| fits | records | CPU s summed: before -> after (ratio) | per-record ratio: median "
          "[range] | median CPU s | same gamma and interval | identified | covered | median "
          "relative error |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name in sorted(set(variants(before)) | set(variants(after))):
        o = compare(before, after, name, skip)
        if "cpu_before" in o:
            cpu = f"{o['cpu_before']:.1f} -> {o['cpu_after']:.1f} ({o['sum_ratio']:.2f})"
            per = f"{o['median_ratio']:.2f} [{o['min_ratio']:.2f}, {o['max_ratio']:.2f}]"
            med = f"{o['median_cpu_before']:.2f} -> {o['median_cpu_after']:.2f}"
        else:
            cpu = per = med = "-"
        print(f"| {name} | {o['records']} | {cpu} | {per} | {med} | {o['same_answer']} of "
              f"{o['records']} | {o['identified_before']} -> {o['identified_after']} | "
              f"{o['covered_before']} -> {o['covered_after']} | "
              f"{fmt(o['median_rel_err_before'], '.2e')} -> "
              f"{fmt(o['median_rel_err_after'], '.2e')} |")
        if o["changed"]:
            print(f"\n{name}: answer changed on {', '.join(o['changed'])}\n", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
