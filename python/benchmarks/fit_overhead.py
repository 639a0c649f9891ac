#!/usr/bin/env python3
"""Time csympnet.fit against `csympnet fit` on the same S1 pairs and budget (docs/python.md).

    PYTHONPATH=build/python /usr/bin/python3 python/benchmarks/fit_overhead.py \
        --cli build/bin/csympnet [--epochs 50000] [--repeats 5]

Runs alternate (CLI, Python, CLI, ...) so that load from other processes hits both alike.
Reports, per side, the median over repeats of the wall time of the whole fit (CLI: the whole
process, including reading the CSV and writing the model; Python: the fit() call) and of the
training loop alone (TrainSummary.seconds), and checks that both sides learned the same bits.
"""

import argparse
import json
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import csympnet


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--cli", required=True, help="path of the csympnet binary")
    parser.add_argument("--epochs", type=int, default=50000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        pairs = csympnet.generate("s1", "train")
        csympnet.write_csv(tmp / "s1.csv", pairs)
        cli_wall, cli_train, py_wall, py_train = [], [], [], []
        for r in range(args.repeats):
            out = tmp / f"cli{r}"
            t0 = time.perf_counter()
            subprocess.run([args.cli, "fit", str(tmp / "s1.csv"), "--recipe", "classic",
                            "--epochs", str(args.epochs),
                            "--out", str(out), "-q"], check=True, capture_output=True)
            cli_wall.append(time.perf_counter() - t0)
            cli_train.append(json.loads((out / "report.json").read_text())["train_seconds"])

            t0 = time.perf_counter()
            model = csympnet.fit(*pairs, epochs=args.epochs)
            py_wall.append(time.perf_counter() - t0)
            py_train.append(model.training["seconds"])
        same = np.array_equal(model.params, csympnet.load(out / "model.json").params)

    med = statistics.median
    print(f"S1, {len(pairs.h)} pairs, {args.epochs} epochs, {args.repeats} repeats (medians):")
    print(f"  CLI  `csympnet fit`   wall {med(cli_wall):.3f} s   training loop {med(cli_train):.3f} s")
    print(f"  Python csympnet.fit   wall {med(py_wall):.3f} s   training loop {med(py_train):.3f} s")
    print(f"  Python/CLI: wall {med(py_wall) / med(cli_wall):.3f}, "
          f"training loop {med(py_train) / med(cli_train):.3f}")
    print(f"  same parameters to the bit: {same}")
    print(f"  all CLI walls {[round(x, 3) for x in cli_wall]}, Python {[round(x, 3) for x in py_wall]}")


if __name__ == "__main__":
    main()
