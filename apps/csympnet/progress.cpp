#include "progress.hpp"

#include "interrupt.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>

namespace csympnet::cli {

ProgressLine::ProgressLine(bool quiet)
    : active_(!quiet && isatty(STDERR_FILENO) == 1), start_(std::chrono::steady_clock::now()) {}

ProgressLine::~ProgressLine() {
  if (drawn_) std::fputc('\n', stderr);
}

ProgressCallback ProgressLine::callback() {
  if (!active_) return [](const TrainProgress&) { return !interrupted(); };
  return [this](const TrainProgress& p) {
    if (interrupted()) return false;
    // Redraw at most 10 times a second, and always at the end of a stage. The clock is the
    // line's own: each stage (AdamW, then LM or L-BFGS) counts its seconds from its start.
    const double now =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    if (now - last_draw_ < 0.1 && p.epoch != p.epochs) return true;
    last_draw_ = now;
    const double eta = p.epoch > 0 ? p.seconds * static_cast<double>(p.epochs - p.epoch) /
                                         static_cast<double>(p.epoch)
                                   : 0.0;
    const bool adamw = std::strcmp(p.stage, "adamw") == 0;
    const bool bootstrap = std::strcmp(p.stage, "bootstrap") == 0;
    std::fprintf(stderr, "\r\033[K%s %ld/%ld  ",
                 adamw       ? "epoch"
                 : bootstrap ? "bootstrap replicate"
                             : p.stage,
                 p.epoch, p.epochs);
    if (!std::isnan(p.train_loss)) std::fprintf(stderr, "loss %.3e  ", p.train_loss);
    if (!std::isnan(p.val_loss))
      std::fprintf(stderr, "val %.3e  best %.3e  ", p.val_loss, p.best_val_loss);
    if (!std::isnan(p.gamma_hat)) std::fprintf(stderr, "gamma_hat %.7f  ", p.gamma_hat);
    // An LM or L-BFGS budget is a cap that tolerances usually end sooner: no ETA for them.
    if (adamw || bootstrap) std::fprintf(stderr, "ETA %.1fs", eta);
    std::fflush(stderr);
    drawn_ = true;
    return true;
  };
}

}  // namespace csympnet::cli
