// `train` and `fit`: learn a one-step map from a user's CSV (pairs or trajectories).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "commands.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/data/csv.hpp"
#include "csympnet/experiments/fit.hpp"
#include "csympnet/experiments/outputs.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/io/model_file.hpp"
#include "csympnet/train/loss.hpp"
#include "interrupt.hpp"
#include "progress.hpp"

namespace csympnet::cli {

namespace {
struct FitArgs {
  std::string data, val, out, model = "csympnet", core, lr_schedule = "cosine";
  double lr = 1e-3;
  std::uint64_t seed = 42;
  long epochs = 0;
  long val_every = 10;
  double val_fraction = 0.2, beta_init = 0.1;
  bool no_beta_decay = false, quiet = false, force = false;
};

// "la:L:m" or "g:L:w".
nlohmann::json parse_core(const std::string& s) {
  const std::string expected = "expected la:LAYERS:SUBLAYERS or g:LAYERS:WIDTH, e.g. la:5:20";
  const auto c1 = s.find(':');
  const auto c2 = c1 == std::string::npos ? c1 : s.find(':', c1 + 1);
  if (c2 == std::string::npos) throw Error("--core '" + s + "': " + expected);
  const std::string type = s.substr(0, c1);
  int a = 0, b = 0;
  try {
    std::size_t pa = 0, pb = 0;
    const std::string sa = s.substr(c1 + 1, c2 - c1 - 1), sb = s.substr(c2 + 1);
    a = std::stoi(sa, &pa);
    b = std::stoi(sb, &pb);
    if (pa != sa.size() || pb != sb.size()) throw std::invalid_argument("trailing text");
  } catch (const std::exception&) {
    throw Error("--core '" + s + "': " + expected);
  }
  if (a < 1 || b < 1) throw Error("--core '" + s + "': sizes must be >= 1");
  if (type == "la") return {{"type", "la"}, {"layers", a}, {"sublayers", b}};
  if (type == "g") return {{"type", "g"}, {"layers", a}, {"width", b}};
  throw Error("--core '" + s + "': unknown core type '" + type + "'; " + expected);
}

void add_fit_options(CLI::App& cmd, FitArgs& a) {
  cmd.add_option("--model", a.model, "csympnet (default) or sympnet")
      ->check(CLI::IsMember({"csympnet", "sympnet"}));
  cmd.add_option("--core", a.core, "Symplectic core: la:L:m or g:L:w (default: by dimension)");
  cmd.add_option("--epochs", a.epochs, "Epoch budget (default: by dimension)")
      ->check(CLI::Range(1L, 100000000L));
  cmd.add_option("--lr", a.lr, "AdamW learning rate (default 1e-3)")
      ->check(CLI::Range(1e-12, 10.0));
  cmd.add_option("--lr-schedule", a.lr_schedule, "cosine (default) or constant (the paper's)")
      ->check(CLI::IsMember({"constant", "cosine"}));
  cmd.add_option("--val-every", a.val_every, "Validate every K epochs (default 10)")
      ->check(CLI::Range(1L, 100000000L));
  cmd.add_option("--seed", a.seed, "Seed of the validation split and the init (default 42)");
  cmd.add_option("--val-fraction", a.val_fraction,
                 "Held-out share when no --val is given (default 0.2)")
      ->check(CLI::Range(0.01, 0.99));
  cmd.add_option("--beta-init", a.beta_init, "Initial beta of CSympNet-ID (nonzero)");
  cmd.add_flag("--no-beta-decay", a.no_beta_decay, "Exclude beta from weight decay");
  cmd.add_option("--out", a.out, "Output directory")->required();
  cmd.add_flag("--force", a.force, "Allow writing into a non-empty output directory");
  cmd.add_flag("-q,--quiet", a.quiet, "No progress line");
}

void run_fit(const FitArgs& a, bool verbose_summary) {
  prepare_output_dir(a.out, a.force);
  const PairSet data = read_any_as_pairs(a.data);
  std::optional<PairSet> val;
  if (!a.val.empty()) val = read_any_as_pairs(a.val);
  FitConfig c;
  c.model = a.model;
  if (!a.core.empty()) c.core = parse_core(a.core);
  c.seed = a.seed;
  c.val_fraction = a.val_fraction;
  c.beta_init = a.beta_init;
  c.train.epochs = a.epochs;
  c.train.val_every = a.val_every;
  c.train.adamw.lr = a.lr;
  c.train.lr_schedule = a.lr_schedule;
  c.train.adamw.decay_damping = !a.no_beta_decay;
  FitResult r;
  {
    ProgressLine progress(a.quiet);
    r = fit_pairs(data, val, c, progress.callback());
  }
  const auto gamma = r.model.damping_rate(r.theta);
  const double train_loss = one_step_loss(*r.model.map, r.theta, r.train);
  nlohmann::json report = {
      {"model", r.config.model},
      {"data", a.data},
      {"validation", a.val.empty() ? nlohmann::json("split") : nlohmann::json(a.val)},
      {"d", data.d()},
      {"pairs_train", r.train.size()},
      {"pairs_val", r.val.size()},
      {"h_min", data.h.minCoeff()},
      {"h_max", data.h.maxCoeff()},
      {"params", r.model.n_params()},
      {"seed", a.seed},
      {"epochs", r.training.epochs_run},
      {"train_seconds", r.training.seconds},
      {"best_val_loss", r.training.best_val_loss},
      {"train_loss", train_loss},
      {"gamma_hat", gamma ? nlohmann::json(*gamma) : nlohmann::json(nullptr)},
      {"training", r.training},
      {"config", r.config},
      {"architecture", r.model.hyperparams()}};
  write_json_file((std::filesystem::path(a.out) / "report.json").string(), report);
  save_model((std::filesystem::path(a.out) / "model.json").string(), r.model, r.theta,
             {{"data", a.data}, {"seed", a.seed}, {"train", r.config.train}});
  if (gamma) std::printf("gamma_hat = %.10g\n", *gamma);
  if (verbose_summary || !a.quiet) {
    std::printf("%s, d = %lld, %lld training / %lld validation pairs, %lld params\n",
                r.config.model.c_str(), static_cast<long long>(data.d()),
                static_cast<long long>(r.train.size()), static_cast<long long>(r.val.size()),
                static_cast<long long>(r.model.n_params()));
    std::printf("%s\n", r.training.brief_report().c_str());
    std::printf("train loss %.3e, validation loss %.3e; wrote %s/{report.json,model.json}\n",
                train_loss, r.training.best_val_loss, a.out.c_str());
  }
  if (r.training.stop_reason == "diverged")
    throw Error("training diverged (non-finite loss); the best checkpoint was kept in " + a.out);
  if (interrupted())
    throw Interrupted("stopped at epoch " + std::to_string(r.training.epochs_run) +
                      "; the best checkpoint (epoch " + std::to_string(r.training.best_epoch) +
                      ") and its report are in " + a.out);
}
}  // namespace

void add_train(CLI::App& app) {
  auto a = std::make_shared<FitArgs>();
  CLI::App* cmd = app.add_subcommand("train", "Train a model on pairs (or trajectories) CSV");
  cmd->add_option("--data", a->data, "Training CSV (pairs or trajectories)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--val", a->val, "Validation CSV (default: a split of --data)")
      ->check(CLI::ExistingFile);
  add_fit_options(*cmd, *a);
  cmd->callback([a] { run_fit(*a, false); });
}

void add_fit(CLI::App& app) {
  auto a = std::make_shared<FitArgs>();
  CLI::App* cmd = app.add_subcommand(
      "fit", "Fit CSympNet-ID to your own pairs or trajectories and print gamma_hat");
  cmd->add_option("data", a->data, "CSV of pairs or trajectories")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--val", a->val, "Validation CSV (default: a split of DATA)")
      ->check(CLI::ExistingFile);
  add_fit_options(*cmd, *a);
  cmd->callback([a] { run_fit(*a, true); });
}

}  // namespace csympnet::cli
