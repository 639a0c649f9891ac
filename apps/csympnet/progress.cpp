#include "progress.hpp"

#include "interrupt.hpp"

#include "csympnet/train/termination_words.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>

namespace csympnet::cli {

const char* stage_words(const char* stage) {
  if (std::strcmp(stage, "adamw") == 0) return "AdamW epoch";
  if (std::strcmp(stage, "bootstrap") == 0) return "bootstrap replicate";
  if (std::strcmp(stage, "lm") == 0) return "Levenberg-Marquardt iteration";
  if (std::strcmp(stage, "lbfgs") == 0) return "L-BFGS iteration";
  return stage;
}

std::string ending_words(const std::string& termination) {
  return termination_words(termination);
}

std::string lm_summary_words(long iterations, long accepted, long kept_iterate,
                             const std::string& termination) {
  return "Levenberg-Marquardt: " + std::to_string(iterations) + " iterations (" +
         std::to_string(accepted) + " accepted), " + ending_words(termination) + "; kept iterate " +
         std::to_string(kept_iterate) + ", the best on held-out data";
}

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
    // An LM or L-BFGS budget is a cap: "iteration 12, at most 300", not "12/300".
    if (adamw || bootstrap)
      std::fprintf(stderr, "\r\033[K%s %ld/%ld  ", stage_words(p.stage), p.epoch, p.epochs);
    else
      std::fprintf(stderr, "\r\033[K%s %ld (at most %ld)  ", stage_words(p.stage), p.epoch,
                   p.epochs);
    if (!std::isnan(p.train_loss)) std::fprintf(stderr, "train loss %.3e  ", p.train_loss);
    if (!std::isnan(p.val_loss))
      std::fprintf(stderr, "held-out loss %.3e (best %.3e)  ", p.val_loss, p.best_val_loss);
    if (!std::isnan(p.gamma_hat)) std::fprintf(stderr, "gamma_hat %.7f  ", p.gamma_hat);
    // An LM or L-BFGS budget is a cap that tolerances usually end sooner: no ETA for them.
    if (adamw || bootstrap) std::fprintf(stderr, "ETA %.1fs", eta);
    std::fflush(stderr);
    drawn_ = true;
    return true;
  };
}

}  // namespace csympnet::cli
