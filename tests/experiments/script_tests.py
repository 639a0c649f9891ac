"""The runner of the experiments' test scripts when ctest runs them as plain scripts (no pytest):
every test_ function of the module in name order, each reported with its CPU seconds, every
failure reported before the exit status 1."""
import sys
import time


def run(namespace):
    """Runs the test_ functions of `namespace` (a module's globals()) and exits."""
    failed = 0
    for name, fn in sorted(namespace.items()):
        if name.startswith("test_") and callable(fn):
            t0 = time.process_time()
            try:
                fn()
                print(f"ok   {name} ({time.process_time() - t0:.2f} CPU s)")
            except Exception as e:  # report every failing test, then exit 1
                failed += 1
                print(f"FAIL {name}: {type(e).__name__}: {e}")
    sys.exit(1 if failed else 0)
