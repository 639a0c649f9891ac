"""`python -m csympnet ARGS` runs the command line `csympnet ARGS` (csympnet._cli)."""

import sys

from ._cli import main

if __name__ == "__main__":
    sys.exit(main())
