#!/usr/bin/python3
"""`make bench`: csympnet's training speed beside PyTorch's, as one table measured in one run.

For each preset (s1, s2, s3, s2-100), one full-batch CSympNet-ID epoch (forward, backward,
AdamW, the PROTOCOL settings) is timed
  * in csympnet: Google Benchmark `epoch/P/csympnet` of build/bin/csympnet_bench (median of
    --repetitions runs, wall time);
  * in PyTorch: bench/torch_peer.py, the same model, data, initial θ and optimiser in float64,
    after checking that its losses match csympnet's to 1e-12 (relative).
Beside them: the analytic FLOPs per epoch (docs/benchmarks.md), our FLOP rate as a fraction of
the machine's dgemm rate measured in the same run (Eigen in csympnet_bench, OpenBLAS through
torch, at the s2-100 product shape 100x100x400), and the peak resident memory of a training
run (`csympnet run --preset P --epochs N`, getrusage of the child).

Both sides get the same number of threads (--threads, default 1: csympnet's training loop is
single-threaded, so PyTorch's intra-op pool and OpenBLAS get 1 too).
Needs Debian's python3-torch on a threaded OpenBLAS (libopenblas0-pthread); see --help.
"""

import argparse
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
PRESETS = ["s1", "s2", "s3", "s2-100"]
# The goals: PyTorch time / ours, and (s2-100) ours within this factor of the dgemm floor.
GOALS = {"s1": 1000.0, "s2": 10.0, "s3": 10.0, "s2-100": 3.0}
FLOOR_FACTOR_GOAL = 1.5
RSS_EPOCHS = {"s1": 2000, "s2": 200, "s3": 200, "s2-100": 20}
REPRESENTATIVE_GEMM = "100x100x400"
DEPS_HELP = """\
bench_table: PyTorch is needed for the side-by-side, on a threaded BLAS, as a pip install
would have it (Debian's default reference BLAS is ~20x slower and would flatter csympnet):
    sudo apt-get install python3-torch libopenblas0-pthread
(run with --no-torch to print csympnet's columns alone)."""


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"), help="CMake build directory")
    ap.add_argument("--presets", default=",".join(PRESETS))
    ap.add_argument("--threads", type=int, default=1, help="threads for PyTorch and OpenBLAS")
    ap.add_argument("--repetitions", type=int, default=5,
                    help="Google Benchmark repetitions per epoch benchmark (median reported)")
    ap.add_argument("--min-time", type=float, default=1.0,
                    help="seconds per timing (each repetition, and each PyTorch variant)")
    ap.add_argument("--no-torch", action="store_true", help="skip the PyTorch columns")
    ap.add_argument("--no-rss", action="store_true", help="skip the peak-memory runs")
    ap.add_argument("--json", help="also write every measurement to this file")
    return ap.parse_args()


def load_average():
    return "%.2f %.2f %.2f" % os.getloadavg()


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def check_torch():
    """(ok, message): torch importable and on OpenBLAS."""
    probe = ("import torch, json; maps = open('/proc/self/maps').read(); "
             "print(json.dumps([l.split()[-1] for l in maps.splitlines() if 'blas' in l]))")
    r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    if r.returncode != 0:
        return False, "PyTorch is not importable by " + sys.executable
    libs = json.loads(r.stdout.strip().splitlines()[-1])
    if not any("openblas" in lib for lib in libs):
        return False, "PyTorch runs on " + (", ".join(libs) or "no BLAS") + ", not OpenBLAS"
    return True, ""


def run_micro(bench, presets, repetitions, min_time):
    names = "|".join(f"epoch/{p}/csympnet" for p in presets)
    filt = f"^({names}|dgemm/eigen/.*)$"
    with tempfile.NamedTemporaryFile(suffix=".json") as out:
        r = subprocess.run([bench, f"--benchmark_filter={filt}",
                            f"--benchmark_repetitions={repetitions}",
                            f"--benchmark_min_time={min_time}",
                            "--benchmark_report_aggregates_only=true",
                            f"--benchmark_out={out.name}", "--benchmark_out_format=json"],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if r.returncode != 0:
            sys.stderr.write(r.stderr)
            raise SystemExit("bench_table: csympnet_bench failed (see above)")
        with open(out.name) as f:
            doc = json.load(f)
    results = {}
    for b in doc["benchmarks"]:
        if b.get("aggregate_name", "median") != "median":
            continue
        name = b.get("run_name", b["name"])
        unit = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}[b["time_unit"]]
        results[name] = {"seconds": b["real_time"] * unit, "cpu_seconds": b["cpu_time"] * unit,
                         "flops": b.get("flop_per_epoch"), "rate": b.get("FLOPS"),
                         "params": b.get("params"), "pairs": b.get("pairs")}
    return results, doc.get("context", {})


def run_torch(bench, presets, threads, min_time, workdir):
    subprocess.run([bench, f"--peer-export={workdir}", f"--peer-presets={','.join(presets)}"],
                   check=True)
    cmd = [sys.executable, os.path.join(HERE, "torch_peer.py"), "--dir", workdir,
           "--presets", ",".join(presets), "--threads", str(threads),
           "--min-time", str(min_time), "--dgemm", REPRESENTATIVE_GEMM + ",1000x1000x1000"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    records = [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]
    if r.returncode != 0:
        sys.stderr.write(r.stderr)
        raise SystemExit("bench_table: torch_peer.py failed (see above)")
    env = next(x for x in records if x["kind"] == "environment")
    per_preset = {x["preset"]: x for x in records if x["kind"] == "preset"}
    return env, per_preset


def peak_rss_mb(cli, preset, epochs, workdir):
    out = os.path.join(workdir, "rss-" + preset)
    proc = subprocess.Popen([cli, "run", "--preset", preset, "--model", "csympnet", "--epochs",
                             str(epochs), "--out", out, "--force", "-q"],
                            stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"bench_table: csympnet run --preset {preset} failed")
    return usage.ru_maxrss / 1024.0  # KiB on Linux


def fmt_ms(seconds):
    ms = seconds * 1e3
    return f"{ms:.4f}" if ms < 0.1 else f"{ms:.3f}" if ms < 10 else f"{ms:.2f}"


def main():
    args = parse_args()
    presets = [p for p in args.presets.split(",") if p]
    bench = os.path.join(args.build, "bin", "csympnet_bench")
    cli = os.path.join(args.build, "bin", "csympnet")
    for path in (bench, cli):
        if not os.access(path, os.X_OK):
            raise SystemExit(f"bench_table: {path} not found; build first (make build)")
    use_torch = not args.no_torch
    if use_torch:
        ok, why = check_torch()
        if not ok:
            print(f"bench_table: {why}.\n{DEPS_HELP}", file=sys.stderr)
            sys.exit(2)

    load_before = load_average()
    record = {"machine": cpu_model(), "cores": os.cpu_count(), "threads": args.threads,
              "load_before": load_before}
    micro, context = run_micro(bench, presets, args.repetitions, args.min_time)
    record["micro"] = micro
    record["exact_product"] = context.get("exact_product", "?")
    workdir = tempfile.mkdtemp(prefix="csympnet-bench-")
    try:
        torch_env, torch_runs = ({}, {})
        if use_torch:
            torch_env, torch_runs = run_torch(bench, presets, args.threads, args.min_time, workdir)
        record["torch"] = {"environment": torch_env, "presets": torch_runs}
        rss = {}
        if not args.no_rss:
            for p in presets:
                rss[p] = peak_rss_mb(cli, p, RSS_EPOCHS.get(p, 100), workdir)
        record["peak_rss_mb"] = rss
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    record["load_after"] = load_average()

    eigen_gemm = micro.get(f"dgemm/eigen/{REPRESENTATIVE_GEMM}", {}).get("rate") or 0.0
    blas_gemm = torch_env.get("dgemm_gflops", {}).get(REPRESENTATIVE_GEMM, 0.0) * 1e9
    machine_gemm = max(eigen_gemm, blas_gemm)

    print(f"csympnet training epoch vs PyTorch {torch_env.get('torch', '(not run)')}, float64, "
          f"full batch, AdamW")
    print(f"machine: {record['machine']}, {record['cores']} cores; threads: csympnet 1, "
          f"PyTorch+OpenBLAS {args.threads if use_torch else '-'}; "
          f"csympnet products: {record['exact_product']}")
    print(f"dgemm {REPRESENTATIVE_GEMM}: Eigen {eigen_gemm / 1e9:.1f} GFLOP/s, OpenBLAS "
          f"{blas_gemm / 1e9:.1f} GFLOP/s -> machine rate {machine_gemm / 1e9:.1f} GFLOP/s")
    print(f"load average: {load_before} before, {record['load_after']} after")
    header = ["preset", "params", "FLOP/epoch", "ours ms", "PyTorch ms", "ratio",
              "goal", "ours GFLOP/s", "of dgemm", "x floor", "peak RSS MB"]
    rows = []
    for p in presets:
        m = micro.get(f"epoch/{p}/csympnet")
        if m is None:
            continue
        t = torch_runs.get(p)
        ratio = t["seconds_per_epoch"] / m["seconds"] if t else None
        rate = m["flops"] / m["seconds"]
        frac = rate / machine_gemm if machine_gemm else None
        goal = f">={GOALS[p]:g}x" if p in GOALS else ""
        if p == "s2-100":
            goal += f", <={FLOOR_FACTOR_GOAL:g}x floor"
        rows.append([p, f"{m['params']:.0f}", f"{m['flops'] / 1e6:.3f} M", fmt_ms(m["seconds"]),
                     fmt_ms(t["seconds_per_epoch"]) if t else "-",
                     f"{ratio:.0f}x" if ratio and ratio >= 10 else f"{ratio:.2f}x" if ratio else "-",
                     goal, f"{rate / 1e9:.2f}", f"{frac:.0%}" if frac else "-",
                     f"{1 / frac:.2f}" if frac else "-",
                     f"{rss[p]:.0f}" if p in rss else "-"])
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    print("| " + " | ".join(h.ljust(w) for h, w in zip(header, widths)) + " |")
    print("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for r in rows:
        print("| " + " | ".join(c.ljust(w) for c, w in zip(r, widths)) + " |")
    if use_torch:
        variants = ", ".join(f"{p} {torch_runs[p]['adamw']}" for p in presets if p in torch_runs)
        print(f"PyTorch: eager nn.Module + autograd, torch.optim.AdamW (the faster of its loop and "
              f"foreach implementations, timed: {variants}); median of timed batches")
        worst = max(x["loss_rel_diff_max"] for x in torch_runs.values())
        print(f"same computation: PyTorch's losses over the first "
              f"{next(iter(torch_runs.values()))['loss_epochs_checked']} epochs match csympnet's to "
              f"{worst:.1e} (relative) on every preset")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
