"""The figure of a `csympnet fit` output directory: OUT/fit.png and OUT/fit.pdf.

    python3 -m csympnet.fit_figure OUT [--data FILE] [--path BASE]

`csympnet fit` runs this after it has written report.json and model.json (unless
--no-figures). It reads the record named in report.json ("data": "file", with the "columns"
map of --columns), runs the fitted model freely over the record's own sample times and draws:

  - each dof's positions, record against the free run (one panel per dof up to three; with
    more dofs the first three and a summary of every dof's free-run error);
  - the residuals, record minus free run;
  - the amplitude envelope: the peaks of |q - centre| in each half-cycle of the free run, for
    the record and the free run, beside A0 exp(-gamma_hat t / 2). gamma_hat is the energy's
    decay rate (energy ~ exp(-gamma_hat t)), so amplitudes decay at gamma_hat / 2;
  - the modes (angular frequency and damping ratio with their intervals) and gamma_hat.

A driven record (u1..um columns) is run fed its inputs from the state fitted to its first
window of positions, and the envelope gives way to the fitted map's linearised frequency
response |q_i / u_j| with its modes marked (Model.frequency_response).

The free run of a record with momenta starts at its first state; for positions alone it
starts at the state that the model fits to the first window of positions
(Model.state_from_positions), at the window's last time. With several trajectories the
longest is drawn (the title says which). The record is read with NumPy (the CSV layout of
docs/data-formats.md) and the free run computed in _fit_record.py, which alone needs the
compiled module, for the model's rollouts; plot.fit_figure draws the figure.

On failure the command prints one line, "fit_figure: WHY", to standard error and exits 1.
"""

import os
import sys

from ._fit_record import free_run, read_record  # noqa: F401 (this module's names, kept)

try:
    from . import plot
except ImportError as e:  # matplotlib missing: draw() says so in one line
    plot, _PLOT_ERROR = None, e

#: The figure's file name in the output directory, without its suffix (.png and .pdf).
FIGURE_NAME = "fit"


def draw(out_dir, data=None, path=None, *, model=None, size="page"):
    """The figure of the `csympnet fit` output directory `out_dir` (see the module's text).
    data: the record (default: report.json's "data" "file", relative to the working
    directory, read with its "columns" map); model: a loaded Model (default: out_dir's
    model.json). path: save as PATH.png and PATH.pdf (None: do not save). Returns the Figure."""
    if plot is None:
        raise ImportError(f"the figure needs matplotlib ({_PLOT_ERROR})")
    return plot.fit_figure(out_dir, data, path, model=model, size=size)


def main(argv=None):
    import argparse

    parser = argparse.ArgumentParser(
        prog="python3 -m csympnet.fit_figure",
        description="Draws OUT/fit.png and OUT/fit.pdf from a `csympnet fit` output directory.")
    parser.add_argument("out", help="the output directory of `csympnet fit`")
    parser.add_argument("--data", help="the record (default: report.json's data file)")
    parser.add_argument("--path", help="save as PATH.png and PATH.pdf (default: OUT/fit)")
    args = parser.parse_args(argv)
    try:
        draw(args.out, args.data, args.path or os.path.join(args.out, FIGURE_NAME))
    except KeyboardInterrupt:
        print("fit_figure: interrupted", file=sys.stderr)
        return 130
    except Exception as e:  # one line for the CLI's note; the traceback helps no user
        text = " ".join(str(e).split()) or type(e).__name__
        print(f"fit_figure: {text}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
