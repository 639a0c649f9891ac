#include "progress.hpp"

#include "interrupt.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdio>

namespace csympnet::cli {

ProgressLine::ProgressLine(bool quiet) : active_(!quiet && isatty(STDERR_FILENO) == 1) {}

ProgressLine::~ProgressLine() {
  if (drawn_) std::fputc('\n', stderr);
}

ProgressCallback ProgressLine::callback() {
  if (!active_) return [](const TrainProgress&) { return !interrupted(); };
  return [this](const TrainProgress& p) {
    if (interrupted()) return false;
    // Redraw at most 10 times a second, and always at the end.
    if (p.seconds - last_draw_ < 0.1 && p.epoch != p.epochs) return true;
    last_draw_ = p.seconds;
    const double eta = p.epoch > 0 ? p.seconds * static_cast<double>(p.epochs - p.epoch) /
                                         static_cast<double>(p.epoch)
                                   : 0.0;
    std::fprintf(stderr, "\r\033[Kepoch %ld/%ld  loss %.3e  val %.3e  best %.3e", p.epoch, p.epochs,
                 p.train_loss, p.val_loss, p.best_val_loss);
    if (!std::isnan(p.gamma_hat)) std::fprintf(stderr, "  gamma_hat %.7f", p.gamma_hat);
    std::fprintf(stderr, "  ETA %.1fs", eta);
    std::fflush(stderr);
    drawn_ = true;
    return true;
  };
}

}  // namespace csympnet::cli
