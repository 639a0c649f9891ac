"""Progress bars for verbose=True: one bar per stage (AdamW epochs, then each LM or L-BFGS run),
drawn by tqdm where it is installed (Debian: python3-tqdm), else one plain line a second."""

import contextlib
import sys
import time

try:
    from tqdm import tqdm as _tqdm
except ImportError:  # tqdm is optional
    _tqdm = None

# The bar's name of each stage.
_STAGE_NAMES = {"adamw": "AdamW epochs", "lm": "LM iterations (Levenberg-Marquardt)",
                "lbfgs": "L-BFGS iterations", "bootstrap": "bootstrap replicates"}
# An LM or L-BFGS budget is a cap that the optimiser usually does not reach (it stops once it
# has converged): its bar ends full where the stage ended, and the plain line says "at most".
_CAPPED = ("lm", "lbfgs")


class _Bars:
    """A progress callback (csympnet.fit's `progress=`) that draws the bars."""

    def __init__(self, file=None):
        self._file = file if file is not None else sys.stderr
        self._bar = None
        self._stage = None
        self._last = -1
        self._printed = 0.0

    def __call__(self, p):
        stage = p.get("stage", "adamw")
        if stage != self._stage or p["epoch"] < self._last:  # a new stage, or a new run of it
            self.close()
            self._stage = stage
            if _tqdm is not None:
                unit = {"adamw": "epoch", "bootstrap": "replicate"}.get(stage, "it")
                self._bar = _tqdm(total=p["epochs"], desc=_STAGE_NAMES.get(stage, stage),
                                  unit=unit, file=self._file, leave=True, dynamic_ncols=True)
        self._last = p["epoch"]
        info = {} if p.get("val_loss") is None else {"held-out loss": f"{p['val_loss']:.3e}"}
        if p.get("gamma") is not None:
            info["gamma"] = f"{p['gamma']:.6g}"
        if self._bar is not None:
            self._bar.update(p["epoch"] - self._bar.n)
            self._bar.set_postfix(info, refresh=False)
        else:
            now = time.monotonic()
            if now - self._printed >= 1.0 or p["epoch"] == p["epochs"]:
                self._printed = now
                fields = "  ".join(f"{k} {v}" for k, v in info.items())
                count = (f"{p['epoch']} (at most {p['epochs']})" if stage in _CAPPED
                         else f"{p['epoch']}/{p['epochs']}")
                print(f"{_STAGE_NAMES.get(stage, stage)} {count}  {fields}", file=self._file,
                      flush=True)
        return True

    def close(self):
        if self._bar is not None:
            if self._stage in _CAPPED and self._bar.n < (self._bar.total or 0):
                self._bar.total = self._bar.n  # ended before the cap: done, not cut short
                self._bar.refresh()
            self._bar.close()
            self._bar = None


@contextlib.contextmanager
def progress_bars(verbose, file=None):
    """Yields a progress callback drawing bars when `verbose`, else None."""
    if not verbose:
        yield None
        return
    bars = _Bars(file)
    try:
        yield bars
    finally:
        bars.close()


def _check_verbose(verbose):
    if not isinstance(verbose, bool) and type(verbose).__name__ != "bool_":
        raise TypeError(f"verbose: expected True or False, got {type(verbose).__name__}")
    return bool(verbose)


@contextlib.contextmanager
def progress_callback(progress, verbose):
    """The callback for `progress=` and `verbose=` together: the bars draw, and the user's
    callback (if any) decides whether to go on."""
    if progress is not None and not callable(progress):
        raise TypeError("progress: expected a callable taking a dict, or None")
    with progress_bars(_check_verbose(verbose)) as bars:
        if bars is None or progress is None:
            yield bars if progress is None else progress
            return

        def both(p):
            bars(p)
            return progress(p)

        yield both
