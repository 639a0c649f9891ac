#!/usr/bin/python3
"""`make bench`: csympnet's training speed beside PyTorch's, as one table measured in one run.

For each preset (s1, s2, s3, s2-100) and the GEMM-bound workloads s2-100-4k and s2-100-40k
(the s2-100 model, d = 100, on 4,000 and 40,000 pairs), one full-batch CSympNet-ID epoch (forward, backward,
AdamW with the settings of docs/protocol.md, "Training") is timed
  * in csympnet: Google Benchmark `epoch/P/csympnet` of build/bin/csympnet_bench (median of
    --repetitions runs, wall time);
  * in PyTorch: bench/torch_peer.py, the same model, data, initial θ and optimiser in float64,
    after checking that its losses match csympnet's to 1e-12 (relative).
Beside them: the analytic FLOPs per epoch (docs/benchmarks.md), our FLOP rate as a fraction of
the machine's dgemm rate measured in the same run (Eigen in csympnet_bench, OpenBLAS through
torch, at the s2-100 product shape 100x100x400), and the peak resident memory of a training
benchmark process that generates P's pairs and trains on them (getrusage of the child), which
shows how memory grows with the number of pairs (s2-100 on 400, 4,000 and 40,000 pairs).

Beside csympnet's default arithmetic (sse2: the portable build's bits), the same epochs in its
fma arithmetic (CSYMPNET_ARITHMETIC=fma, docs/architecture.md "Arithmetic of the products"),
and one line of MPI scaling: bench/mpi_scaling.py, `csympnet train` at 40,000 pairs in d = 100
on 1 rank, 1 rank x 2 threads and 2 ranks, models compared bit for bit.

--kernels avx2 runs csympnet capped at AVX2 (CSYMPNET_KERNELS=avx2: the kernel forms of a CPU
without AVX-512, same bits), so that a machine with AVX-512 stands in for one without; the table
names the forms that ran.

Each row gives both sides the same number of threads (--threads, default 1,2: a row per preset
and thread count). csympnet's threads are TrainOptions::threads (the epoch split over columns,
docs/architecture.md); PyTorch's are its intra-op pool and OpenBLAS's.
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
PRESETS = ["s1", "s2", "s3", "s2-100", "s2-100-4k", "s2-100-40k"]
# The speed goals: PyTorch time / ours at equal threads, and, on the GEMM-bound d = 100
# workloads, our FLOP rate as a fraction of the machine's dgemm rate measured in the same run.
GOALS = {"s1": 1000.0, "s2": 10.0, "s3": 4.0, "s2-100": 2.0, "s2-100-4k": 2.0, "s2-100-40k": 2.0}
DGEMM_FRACTION_GOAL = {"s2-100": 0.70, "s2-100-4k": 0.70, "s2-100-40k": 0.70}
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
    ap.add_argument("--threads", default="1,2",
                    help="comma-separated thread counts, one row per preset and count (default "
                    "1,2); each row gives both sides that many")
    ap.add_argument("--repetitions", type=int, default=5,
                    help="Google Benchmark repetitions per epoch benchmark (median reported)")
    ap.add_argument("--min-time", type=float, default=1.0,
                    help="seconds per timing (each repetition, and each PyTorch variant)")
    ap.add_argument("--no-torch", action="store_true", help="skip the PyTorch columns")
    ap.add_argument("--no-rss", action="store_true", help="skip the peak-memory runs")
    ap.add_argument("--no-fma", action="store_true",
                    help="skip the column of csympnet's fma arithmetic (CSYMPNET_ARITHMETIC=fma)")
    ap.add_argument("--no-mpi", action="store_true",
                    help="skip the MPI line (bench/mpi_scaling.py: 1 and 2 ranks at 40,000 pairs)")
    ap.add_argument("--kernels", choices=["widest", "avx2", "portable"], default=None,
                    help="csympnet's kernels: the widest this CPU runs, capped at AVX2 (what a "
                    "CPU without AVX-512 runs), or the portable code; sets CSYMPNET_KERNELS for "
                    "every csympnet process (default: the environment's)")
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


def epoch_benchmark(preset, threads):
    return f"epoch/{preset}/csympnet" + (f"/threads:{threads}" if threads > 1 else "")


def run_micro(bench, presets, thread_counts, repetitions, min_time, arithmetic=None):
    names = "|".join(epoch_benchmark(p, t) for p in presets for t in thread_counts)
    filt = f"^({names}|dgemm/eigen/.*)(/real_time)?$"
    env = dict(os.environ)
    env.pop("CSYMPNET_ARITHMETIC", None)
    if arithmetic:
        env["CSYMPNET_ARITHMETIC"] = arithmetic
    with tempfile.NamedTemporaryFile(suffix=".json") as out:
        r = subprocess.run([bench, f"--benchmark_filter={filt}",
                            f"--benchmark_repetitions={repetitions}",
                            f"--benchmark_min_time={min_time}",
                            "--benchmark_report_aggregates_only=true",
                            f"--benchmark_out={out.name}", "--benchmark_out_format=json"],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, env=env)
        if r.returncode != 0:
            sys.stderr.write(r.stderr)
            raise SystemExit("bench_table: csympnet_bench failed (see above)")
        with open(out.name) as f:
            doc = json.load(f)
    results = {}
    for b in doc["benchmarks"]:
        if b.get("aggregate_name", "median") != "median":
            continue
        name = b.get("run_name", b["name"]).removesuffix("/real_time")
        unit = {"ns": 1e-9, "us": 1e-6, "ms": 1e-3, "s": 1.0}[b["time_unit"]]
        results[name] = {"seconds": b["real_time"] * unit, "cpu_seconds": b["cpu_time"] * unit,
                         "flops": b.get("flop_per_epoch"), "rate": b.get("FLOPS"),
                         "params": b.get("params"), "pairs": b.get("pairs")}
    return results, doc.get("context", {})


# PyTorch's thread settings tried for t > 1 threads, fastest kept per preset: (its intra-op
# threads, OpenBLAS's, OMP_WAIT_POLICY or None for the default). With the default policy its
# OpenMP threads spin while OpenBLAS's run, and on 2 cores an s2-100 epoch took 1364 ms
# instead of 15 ms (measured 2026-11-24), which would flatter csympnet absurdly.
def torch_configs(t):
    return [(1, 1, None)] if t == 1 else [(t, t, None), (t, t, "PASSIVE"), (t, 1, "PASSIVE"),
                                          (1, t, "PASSIVE")]


def export_peer_inputs(bench, presets, workdir):
    subprocess.run([bench, f"--peer-export={workdir}", f"--peer-presets={','.join(presets)}"],
                   check=True)


def run_torch(presets, threads, min_time, workdir):
    env, best = None, {}
    for torch_threads, blas_threads, policy in torch_configs(threads):
        cmd = [sys.executable, os.path.join(HERE, "torch_peer.py"), "--dir", workdir,
               "--presets", ",".join(presets), "--threads", str(torch_threads),
               "--blas-threads", str(blas_threads), "--min-time", str(min_time),
               "--dgemm", REPRESENTATIVE_GEMM + ",1000x1000x1000"]
        run_env = dict(os.environ)
        run_env.pop("OMP_WAIT_POLICY", None)
        if policy:
            run_env["OMP_WAIT_POLICY"] = policy
        r = subprocess.run(cmd, capture_output=True, text=True, env=run_env)
        records = [json.loads(line) for line in r.stdout.splitlines() if line.startswith("{")]
        if r.returncode != 0:
            sys.stderr.write(r.stderr)
            raise SystemExit("bench_table: torch_peer.py failed (see above)")
        this_env = next(x for x in records if x["kind"] == "environment")
        config = f"torch {torch_threads}, BLAS {blas_threads}, wait {policy or 'default'}"
        if env is None:
            env = dict(this_env, dgemm_gflops={})
        # The machine's BLAS rate on `threads` threads: OpenBLAS's own count.
        if blas_threads == threads:
            for shape, rate in this_env.get("dgemm_gflops", {}).items():
                env["dgemm_gflops"][shape] = max(rate, env["dgemm_gflops"].get(shape, 0.0))
        for x in records:
            if x["kind"] == "preset":
                x["config"] = config
                p = x["preset"]
                if p not in best or x["seconds_per_epoch"] < best[p]["seconds_per_epoch"]:
                    best[p] = x
    return env, best


def peak_rss_mb(bench, preset, threads):
    """Peak resident memory of a process that generates the preset's pairs and trains on them:
    csympnet_bench running epoch/P/csympnet (at least one epoch), ru_maxrss of the child."""
    name = epoch_benchmark(preset, threads)
    proc = subprocess.Popen([bench, f"--benchmark_filter=^{name}(/real_time)?$",
                             "--benchmark_min_time=0.01"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    err = proc.stderr.read()  # Google Benchmark's banner, or the error
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        sys.stderr.write(err)
        raise SystemExit(f"bench_table: csympnet_bench {name} failed (see above)")
    return usage.ru_maxrss / 1024.0  # KiB on Linux


def run_mpi_scaling(cli, workdir):
    """bench/mpi_scaling.py at 40,000 pairs (1x1, 1x2, 2x1 ranks x threads, 2 runs each): its
    JSON summary, or None where mpirun or an MPI build is missing."""
    if shutil.which("mpirun") is None:
        return None, "mpirun not found"
    out = os.path.join(workdir, "mpi_scaling.json")
    r = subprocess.run([sys.executable, os.path.join(HERE, "mpi_scaling.py"), "--cli", cli,
                        "--reps", "2", "--work", os.path.join(workdir, "mpi"), "--json", out],
                       capture_output=True, text=True)
    if r.returncode != 0 or not os.path.exists(out):
        return None, (r.stderr.strip().splitlines() or ["failed"])[-1]
    with open(out) as f:
        return json.load(f), ""


def fmt_ms(seconds):
    ms = seconds * 1e3
    return f"{ms:.4f}" if ms < 0.1 else f"{ms:.3f}" if ms < 10 else f"{ms:.2f}"


def main():
    args = parse_args()
    if args.kernels is not None:
        os.environ["CSYMPNET_KERNELS"] = "" if args.kernels == "widest" else args.kernels
    presets = [p for p in args.presets.split(",") if p]
    try:
        thread_counts = [int(t) for t in args.threads.split(",") if t]
    except ValueError:
        raise SystemExit(f"bench_table: --threads {args.threads!r}: expected counts like 1,2")
    if not thread_counts or min(thread_counts) < 1:
        raise SystemExit(f"bench_table: --threads {args.threads!r}: expected counts >= 1")
    bench = os.path.join(args.build, "bin", "csympnet_bench")
    for path in (bench,):
        if not os.access(path, os.X_OK):
            raise SystemExit(f"bench_table: {path} not found; build first (make build)")
    use_torch = not args.no_torch
    if use_torch:
        ok, why = check_torch()
        if not ok:
            print(f"bench_table: {why}.\n{DEPS_HELP}", file=sys.stderr)
            sys.exit(2)

    load_before = load_average()
    record = {"machine": cpu_model(), "cores": os.cpu_count(), "threads": thread_counts,
              "load_before": load_before}
    micro, context = run_micro(bench, presets, thread_counts, args.repetitions, args.min_time,
                               "sse2")
    record["micro"] = micro
    micro_fma = {}
    if not args.no_fma:
        micro_fma, _ = run_micro(bench, presets, thread_counts, args.repetitions, args.min_time,
                                 "fma")
        record["micro_fma"] = micro_fma
    record["exact_product"] = context.get("exact_product", "?")
    record["kernels"] = context.get("kernels", "?")
    workdir = tempfile.mkdtemp(prefix="csympnet-bench-")
    torch_env, torch_runs, rss = {}, {}, {}
    try:
        if use_torch:
            export_peer_inputs(bench, presets, workdir)
        for t in thread_counts:
            if use_torch:
                torch_env[t], torch_runs[t] = run_torch(presets, t, args.min_time, workdir)
            if not args.no_rss:
                for p in presets:
                    rss[(p, t)] = peak_rss_mb(bench, p, t)
        mpi, mpi_why = (None, "skipped (--no-mpi)")
        if not args.no_mpi:
            mpi, mpi_why = run_mpi_scaling(os.path.join(args.build, "bin", "csympnet"), workdir)
        record["mpi_scaling"] = mpi
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    record["torch"] = {str(t): {"environment": torch_env.get(t, {}),
                                "presets": torch_runs.get(t, {})} for t in thread_counts}
    record["peak_rss_mb"] = {f"{p}/{t}": v for (p, t), v in rss.items()}
    record["load_after"] = load_average()

    # The machine's dgemm rate at each thread count: the fastest product it ran (Eigen in
    # csympnet_bench runs on one thread; OpenBLAS through torch.mm on t).
    eigen_gemm = micro.get(f"dgemm/eigen/{REPRESENTATIVE_GEMM}", {}).get("rate") or 0.0
    machine_gemm = {}
    for t in thread_counts:
        blas = torch_env.get(t, {}).get("dgemm_gflops", {})
        blas_rate = max(blas.values(), default=0.0) * 1e9
        machine_gemm[t] = max(blas_rate, eigen_gemm if t == 1 else 0.0)
    record["machine_gemm"] = {str(t): r for t, r in machine_gemm.items()}

    torch_version = next((e.get("torch") for e in torch_env.values()), "(not run)")
    print(f"csympnet training epoch vs PyTorch {torch_version}, float64, full batch, AdamW")
    print(f"machine: {record['machine']}, {record['cores']} cores; csympnet products: "
          f"{record['exact_product']}; each row gives csympnet and PyTorch+OpenBLAS its threads")
    print(f"csympnet kernels in use: {record['kernels']}")
    gemm_text = ", ".join(f"{t} thread{'s' if t > 1 else ''} {r / 1e9:.1f}"
                          for t, r in machine_gemm.items())
    print(f"dgemm (fastest of Eigen {REPRESENTATIVE_GEMM} on 1 thread and OpenBLAS "
          f"{REPRESENTATIVE_GEMM} and 1000^3): {gemm_text} GFLOP/s")
    print(f"load average: {load_before} before, {record['load_after']} after")
    header = ["preset", "threads", "pairs", "params", "FLOP/epoch", "ours ms", "PyTorch ms", "ratio",
              "goal", "ours GFLOP/s", "of dgemm", "x floor", "peak RSS MB", "fma ms",
              "fma ratio", "fma of dgemm"]
    def fma_cells(p, t, tr):
        m = micro_fma.get(epoch_benchmark(p, t))
        if m is None:
            return ["-", "-", "-"]
        ratio = tr["seconds_per_epoch"] / m["seconds"] if tr else None
        frac = m["flops"] / m["seconds"] / machine_gemm[t] if machine_gemm.get(t) else None
        return [fmt_ms(m["seconds"]),
                f"{ratio:.0f}x" if ratio and ratio >= 10 else f"{ratio:.2f}x" if ratio else "-",
                f"{frac:.0%}" if frac else "-"]

    rows = []
    for p in presets:
        for t in thread_counts:
            m = micro.get(epoch_benchmark(p, t))
            if m is None:
                continue
            tr = torch_runs.get(t, {}).get(p)
            ratio = tr["seconds_per_epoch"] / m["seconds"] if tr else None
            rate = m["flops"] / m["seconds"]
            frac = rate / machine_gemm[t] if machine_gemm.get(t) else None
            goal = f">={GOALS[p]:g}x" if p in GOALS else ""
            if p in DGEMM_FRACTION_GOAL:
                goal += f", >={DGEMM_FRACTION_GOAL[p]:.0%} dgemm"
            rows.append([p, str(t), f"{m['pairs']:.0f}", f"{m['params']:.0f}", f"{m['flops'] / 1e6:.3f} M",
                         fmt_ms(m["seconds"]), fmt_ms(tr["seconds_per_epoch"]) if tr else "-",
                         f"{ratio:.0f}x" if ratio and ratio >= 10 else
                         f"{ratio:.2f}x" if ratio else "-",
                         goal, f"{rate / 1e9:.2f}", f"{frac:.0%}" if frac else "-",
                         f"{1 / frac:.2f}" if frac else "-",
                         f"{rss[(p, t)]:.0f}" if (p, t) in rss else "-"] + fma_cells(p, t, tr))
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(header)]
    print("| " + " | ".join(h.ljust(w) for h, w in zip(header, widths)) + " |")
    print("|" + "|".join("-" * (w + 2) for w in widths) + "|")
    for r in rows:
        print("| " + " | ".join(c.ljust(w) for c, w in zip(r, widths)) + " |")
    if use_torch:
        runs = [(t, p, x) for t, per in torch_runs.items() for p, x in per.items()]
        variants = ", ".join(f"{p}/{t} {x['adamw']}" for t, p, x in runs)
        print(f"PyTorch: eager nn.Module + autograd, torch.optim.AdamW (the faster of its loop and "
              f"foreach implementations, timed: {variants}); median of timed batches")
        configs = ", ".join(f"{p}/{t}: {x['config']}" for t, p, x in runs if t > 1)
        if configs:
            print(f"PyTorch on more than 1 thread: the fastest of its thread settings, kept: "
                  f"{configs}")
        worst = max(x["loss_rel_diff_max"] for _, _, x in runs)
        print(f"same computation: PyTorch's losses over the first "
              f"{runs[0][2]['loss_epochs_checked']} epochs match csympnet's to "
              f"{worst:.1e} (relative) on every preset")
    if mpi:
        rows_mpi = {(c["ranks"], c["threads"]): c for c in mpi["configs"]}
        one, two = rows_mpi.get((1, 1)), rows_mpi.get((2, 1))
        sent = two["bytes_sent_per_step_per_rank"] if two else []
        print(f"MPI, `csympnet train` at {mpi['pairs']} pairs, d = 100 ({mpi['core']}): 1 rank "
              f"{one['epoch_seconds']:.3f} s/epoch, 2 ranks {two['epoch_seconds']:.3f} s/epoch: "
              f"{two['speedup']:.2f}x (goal >=1.7x); 1 rank x 2 threads "
              f"{rows_mpi[(1, 2)]['speedup']:.2f}x; models bit-identical: {mpi['bit_identical']}; "
              f"sent per rank per step {', '.join(f'{b / 1e6:.1f} MB' for b in sent)}; peak RSS "
              f"per rank {two['peak_rss_mib_per_rank']} MiB")
    else:
        print(f"MPI: not measured ({mpi_why})")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
