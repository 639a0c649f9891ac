#!/usr/bin/python3
"""Identification benchmark: the command line of the package experiments/idbench/ (its
docstring describes the systems, strata, peers and outputs; --help lists the options).

    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/idbench   # 120 cases
    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/idq --quick --only-peers
    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/ido --observed-plan
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from idbench.cli import main  # noqa: E402
from idbench.generate import computed_momenta, generate, plan, write_csv  # noqa: E402,F401
from idbench.peers.oracle import oracle  # noqa: E402,F401
from idbench.peers.sindy import sindy  # noqa: E402,F401

if __name__ == "__main__":
    sys.exit(main())
