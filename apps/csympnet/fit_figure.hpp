// `fit`'s figure (OUT/fit.png, OUT/fit.pdf): drawn by `python3 -m csympnet.fit_figure OUT`
// (python/csympnet/fit_figure.py) in a child process, after report.json and model.json are
// committed. A figure that cannot be drawn never changes what the fit says: the caller prints
// why in one line and keeps the fit's exit code.
#pragma once

#include <string>

namespace csympnet::cli {

// The figure's files in the output directory.
inline constexpr const char* kFitFigureFiles[] = {"fit.png", "fit.pdf"};

struct FigureOutcome {
  bool drawn = false;
  std::string why;  // when not drawn: one line, for the user
};

// Runs the figure module on `out_dir` and waits for it. The interpreter is $CSYMPNET_PYTHON,
// else the build's Python (CSYMPNET_PYTHON_EXECUTABLE, /usr/bin/python3 when none was found);
// the package is looked for beside the executable (BIN/../python, the build tree), then in the
// build's python directory, else left to the interpreter's own path (an installed package).
// The child is started with an argument vector (posix_spawn), never through a shell. On
// SIGINT/SIGTERM (interrupted()) the child is sent SIGINT, and SIGKILL if it has not ended a
// second later, so the command stops promptly; the caller then reports the interruption.
FigureOutcome draw_fit_figure(const std::string& out_dir);

}  // namespace csympnet::cli
