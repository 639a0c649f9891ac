#!/usr/bin/env python3
"""Strong scaling of `csympnet train` over threads and MPI ranks, at d = 100 (the s2-100
preset's model: LA core la:4:4, 161,101 parameters) on 40,000 training pairs.

For ranks x threads in {1x1, 1x2, 2x1} it times the training epochs, checks that the models are
bit-identical, and reports the bytes each rank sends per step (the all-gather of its tree nodes)
and the peak RSS of every rank. `--chunk-scan` times one thread at several --chunk-pairs
(the measurement behind the default chunk size), `--memory` the peak RSS at 4,000 and 40,000
pairs. `--json F` writes a JSON summary.

    python3 bench/mpi_scaling.py --cli build/bin/csympnet --json mpi_scaling.json

An epoch's time is the training time of a run of E epochs (its `training.seconds`: the epochs,
one validation before and one after, on a validation set of 100 pairs, well under 1% of the
time), divided by E. On a shared machine every configuration runs --reps times, the runs
interleaved, and the fastest counts. mpirun is started as the reproduce test starts it (root
allowed, --oversubscribe); --bind-to passes mpirun's binding policy.
"""
import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.abspath(__file__)
CORE = "la:4:4"  # the s2-100 preset's core: 161,101 parameters with CSympNet-ID at d = 100


def rss_child(out_prefix, cmd):
    """Runs cmd (no shell), then writes its peak RSS in KiB to out_prefix.RANK; exits with its
    code. Under mpirun each rank runs one of these."""
    code = subprocess.call(cmd)
    rank = os.environ.get("OMPI_COMM_WORLD_RANK", os.environ.get("PMI_RANK", "0"))
    with open(f"{out_prefix}.{rank}", "w") as f:
        f.write(str(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss))
    sys.exit(code)


def generate(cli, work, split, n):
    path = os.path.join(work, f"{split}{n}.csv")
    if not os.path.exists(path):
        subprocess.run([cli, "generate", "--preset", "s2-100", "--split", split, "--n", str(n),
                        "--out", path], check=True, stdout=subprocess.DEVNULL)
    return path


def train(cli, work, name, data, val, epochs, ranks=1, threads=1, chunk=None, bind=None):
    """One `train` run: (report, model.json text, peak RSS per rank in KiB)."""
    out = os.path.join(work, name)
    shutil.rmtree(out, ignore_errors=True)
    cmd = [cli, "train", data, "--val", val, "--core", CORE, "--epochs", str(epochs),
           "--val-every", str(epochs), "--threads", str(threads), "-q", "--out", out]
    if chunk is not None:
        cmd += ["--chunk-pairs", str(chunk)]
    rss = os.path.join(work, name + ".rss")
    wrapped = [sys.executable, HERE, "--rss-child", rss, "--"] + cmd
    if ranks > 1:
        env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
        wrapped = (["mpirun", "--allow-run-as-root", "--oversubscribe", "-np", str(ranks)] +
                   (["--bind-to", bind] if bind else []) + wrapped)
    else:
        env = None
    subprocess.run(wrapped, check=True, stdout=subprocess.DEVNULL, env=env)
    with open(os.path.join(out, "report.json")) as f:
        report = json.load(f)
    with open(os.path.join(out, "model.json")) as f:
        model = f.read()
    peaks = []
    for r in range(ranks):
        with open(f"{rss}.{r}") as f:
            peaks.append(int(f.read()))
    return report, model, peaks


def aligned_nodes(begin, end):
    """The tree nodes a rank owning chunks [begin, end) sends: the range's largest aligned
    blocks [a, a + 2^k), a a multiple of 2^k (train/chunk_tree.hpp)."""
    nodes, a = 0, begin
    while a < end:
        size = 1
        while a % (2 * size) == 0 and a + 2 * size <= end:
            size *= 2
        nodes += 1
        a += size
    return nodes


def bytes_per_rank(chunks, ranks, params):
    """Bytes each rank sends per step: per node its start, size, gradient and loss."""
    out = []
    for r in range(ranks):
        b, e = chunks * r // ranks, chunks * (r + 1) // ranks
        out.append(aligned_nodes(b, e) * (params + 3) * 8)
    return out


def epoch_seconds(cli, work, name, data, val, epochs, **kw):
    """(seconds per epoch, report, model, peak RSS per rank) of one run."""
    report, model, peaks = train(cli, work, name, data, val, epochs, **kw)
    return report["training"]["seconds"] / epochs, report, model, peaks


def fastest(runs):
    """The run with the least time per epoch, over repetitions."""
    return min(runs, key=lambda r: r[0])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cli", default="build/bin/csympnet", help="the csympnet binary")
    ap.add_argument("--pairs", type=int, default=40000, help="training pairs (default 40000)")
    ap.add_argument("--val-pairs", type=int, default=100,
                    help="validation pairs (default 100: the report's structure check "
                         "computes a Jacobian per validation pair)")
    ap.add_argument("--epochs", type=int, default=3, help="epochs per run (default 3)")
    ap.add_argument("--reps", type=int, default=3, help="runs per configuration (default 3)")
    ap.add_argument("--bind-to", choices=["core", "none"],
                    help="mpirun's binding (default: mpirun's own, core for 2 ranks)")
    ap.add_argument("--chunk-scan", action="store_true",
                    help="also time --chunk-pairs 128..2048 and one chunk on 1 thread at "
                         "4,000 and --pairs pairs")
    ap.add_argument("--memory", action="store_true",
                    help="also the peak RSS of 1-epoch runs at 4,000 and --pairs pairs")
    ap.add_argument("--work", help="directory for data and runs (default: a temporary one)")
    ap.add_argument("--json", help="write the summary here")
    ap.add_argument("--rss-child", help=argparse.SUPPRESS)
    args, rest = ap.parse_known_args()
    if args.rss_child:
        rss_child(args.rss_child, rest[1:] if rest[:1] == ["--"] else rest)
    if rest:
        ap.error(f"unknown arguments {rest}")
    cli = os.path.abspath(args.cli)
    if not os.access(cli, os.X_OK):
        ap.error(f"--cli {args.cli}: not an executable (build it: cmake --build build)")
    if shutil.which("mpirun") is None:
        ap.error("mpirun not found (Debian: openmpi-bin; scripts/install-deps.sh)")
    work = args.work or tempfile.mkdtemp(prefix="csympnet_mpi_scaling_")
    os.makedirs(work, exist_ok=True)
    data = generate(cli, work, "train", args.pairs)
    val = generate(cli, work, "val", args.val_pairs)
    summary = {"date": time.strftime("%Y-%m-%d"), "cpu_count": os.cpu_count(),
               "load_average_at_start": os.getloadavg()[0], "pairs": args.pairs,
               "val_pairs": args.val_pairs, "core": CORE, "epochs_timed": args.epochs,
               "configs": []}
    summary["bind_to"] = args.bind_to or "mpirun default"
    configs = [(1, 1), (1, 2), (2, 1)]
    runs = {c: [] for c in configs}
    for rep in range(args.reps):
        for ranks, threads in configs:
            runs[(ranks, threads)].append(epoch_seconds(
                cli, work, f"r{ranks}t{threads}", data, val, args.epochs, ranks=ranks,
                threads=threads, bind=args.bind_to))
    models = {}
    for ranks, threads in configs:
        t, report, model, peaks = fastest(runs[(ranks, threads)])
        models[(ranks, threads)] = {r[2] for r in runs[(ranks, threads)]}
        tr = report["training"]
        row = {"ranks": ranks, "threads": threads, "epoch_seconds": t,
               "epoch_seconds_all": [r[0] for r in runs[(ranks, threads)]],
               "chunk_pairs": tr.get("chunk_pairs"), "chunks": tr.get("chunks"),
               "params": report["params"],
               "bytes_sent_per_step_rank0": tr.get("bytes_sent_per_step", 0),
               "bytes_sent_per_step_per_rank": bytes_per_rank(tr.get("chunks", 1), ranks,
                                                              report["params"])
               if ranks > 1 else [0],
               "peak_rss_mib_per_rank": [round(p / 1024.0, 1) for p in peaks]}
        summary["configs"].append(row)
        print(json.dumps(row), flush=True)
    base = summary["configs"][0]["epoch_seconds"]
    for row in summary["configs"]:
        row["speedup"] = base / row["epoch_seconds"]
    summary["bit_identical"] = len(set().union(*models.values())) == 1
    # The bytes derived here from the chunk plan match what rank 0 counted.
    for row in summary["configs"]:
        if row["ranks"] > 1 and row["bytes_sent_per_step_per_rank"][0] != row["bytes_sent_per_step_rank0"]:
            print("warning: rank 0's bytes differ from the plan's", file=sys.stderr)
    print(f"bit-identical models: {summary['bit_identical']}")
    for row in summary["configs"]:
        print(f"{row['ranks']} rank(s) x {row['threads']} thread(s): "
              f"{row['epoch_seconds']:.3f} s/epoch, speedup {row['speedup']:.2f}, "
              f"sent {row['bytes_sent_per_step_per_rank']} B/step per rank, "
              f"peak RSS {row['peak_rss_mib_per_rank']} MiB")
    if args.chunk_scan:
        summary["chunk_scan"] = []
        for n in sorted({4000, args.pairs}):
            d = generate(cli, work, "train", n)
            sizes = [128, 256, 512, 1024, 2048, n]
            scan = {c: [] for c in sizes}
            for rep in range(args.reps):
                for c in sizes:
                    scan[c].append(epoch_seconds(cli, work, f"scan{n}_{c}", d, val, args.epochs,
                                                 chunk=c)[0])
            for c in sizes:
                row = {"pairs": n, "chunk_pairs": c, "epoch_seconds": min(scan[c]),
                       "us_per_pair": 1e6 * min(scan[c]) / n, "epoch_seconds_all": scan[c]}
                summary["chunk_scan"].append(row)
                print(json.dumps(row), flush=True)
    if args.memory:
        summary["memory"] = []
        for n in sorted({4000, args.pairs}):
            d = generate(cli, work, "train", n)
            _, _, peaks = train(cli, work, f"mem{n}", d, val, 1)
            row = {"pairs": n, "peak_rss_mib": round(peaks[0] / 1024.0, 1),
                   "csv_mib": round(os.path.getsize(d) / 2**20, 1)}
            summary["memory"].append(row)
            print(json.dumps(row), flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(summary, f, indent=2)
            f.write("\n")
    return 0 if summary["bit_identical"] else 1


if __name__ == "__main__":
    sys.exit(main())
