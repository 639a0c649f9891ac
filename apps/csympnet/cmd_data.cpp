// `generate`: a preset's training/validation pairs or test trajectories as CSV.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "commands.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/data/csv.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/paper/run.hpp"
#include "system_options.hpp"

namespace csympnet::cli {

namespace {
struct GenerateArgs {
  std::string preset, split = "train", out, reference = "splitting";
  std::uint64_t seed = 42;
  std::optional<long> n;
  double sigma = 0.0;
  bool force = false;
  SystemOverrides system;
};
}  // namespace

void add_generate(CLI::App& app) {
  auto a = std::make_shared<GenerateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "generate", "Write a preset's training or validation pairs, or its test trajectories");
  cmd->add_option("--preset", a->preset, "Benchmark preset")
      ->required()
      ->check(one_of(preset_names()));
  cmd->add_option("--split", a->split, "train, val (pairs CSV) or test (trajectories CSV)")
      ->check(one_of({"train", "val", "test"}));
  // kSeed: CLI11 would wrap "-1" into 2^64 - 1 and clamp 2^64 for an unsigned seed.
  cmd->add_option("--seed", a->seed,
                  "Seed (train/val: training seed, default 42; test: data seed, default 0)")
      ->check(kSeed);
  cmd->add_option("--n", a->n, "Number of pairs or trajectories (default: the preset's)")
      ->check(kWholeNumber)
      ->check(in_range(1L, 100000000L));
  cmd->add_option("--sigma", a->sigma, "Relative observation noise (train/val only)")
      ->check(kFiniteNumber)
      ->check(in_range(0.0, 10.0));
  cmd->add_option("--reference", a->reference, "Reference solver")
      ->check(one_of({"splitting", "expm", "rk"}));
  cmd->add_option("--out", a->out, "Output CSV file")->required()->check(kOutputPath);
  cmd->add_flag("--force", a->force, "Overwrite an existing output file");
  a->system.add_to(*cmd);
  cmd->callback([a, cmd] {
    if (parse_only()) return;
    if (std::filesystem::exists(a->out) && !a->force)
      throw Error("--out " + a->out +
                  " already exists; expected a new file name, or --force to overwrite it");
    RunConfig c = default_run_config(a->preset, "csympnet");
    a->system.apply(c.preset);
    c.reference.method = parse_reference(a->reference);
    c.sigma = a->sigma;
    const bool test = a->split == "test";
    c.seed = a->seed;
    c.test_seed = cmd->count("--seed") > 0 ? a->seed : 0;
    if (a->n)
      (test ? c.preset.n_test : (a->split == "train" ? c.preset.n_train : c.preset.n_val)) = *a->n;
    c.validate();
    // Refused before generating: a file larger than csympnet reads back (kMaxInputBytes) is of
    // no use, and its text alone would take that much memory. About 24 bytes a number.
    {
      const double dim = 2.0 * static_cast<double>(c.preset.system.d);
      const double rows =
          test ? static_cast<double>(c.preset.n_test) *
                     (std::floor(c.preset.horizon / c.preset.h_test) + 1.0)
               : static_cast<double>(a->split == "train" ? c.preset.n_train : c.preset.n_val);
      const double per_row = 24.0 * (test ? dim + 2.0 : 2.0 * dim + 1.0);
      const double bytes = rows * per_row;
      const double limit = static_cast<double>(kMaxInputBytes);
      if (bytes > limit) {
        const double per_item =
            test ? per_row * (std::floor(c.preset.horizon / c.preset.h_test) + 1.0) : per_row;
        throw CLI::ValidationError(
            "--n", "the file would hold about " + std::to_string(std::llround(bytes / 1e6)) +
                       " MB, more than the " + std::to_string(kMaxInputBytes >> 20) +
                       " MiB csympnet reads back; expected --n <= " +
                       std::to_string(static_cast<long long>(limit / per_item)) +
                       " for this preset and d");
      }
    }
    // Generates all three splits; they come from independent streams, so this equals what
    // `run` sees for the same seed.
    const RunData d = generate_run_data(c);
    if (test) {
      write_trajectories_csv(a->out, d.test.trajectories);
      std::fprintf(stderr, "wrote %zu test trajectories (%lld redrawn) to %s\n",
                   d.test.trajectories.size(), static_cast<long long>(d.test.redraws),
                   a->out.c_str());
    } else {
      const PairSet& pairs = a->split == "train" ? d.train : d.val;
      write_pairs_csv(a->out, pairs);
      std::fprintf(stderr, "wrote %lld %s pairs to %s\n", static_cast<long long>(pairs.size()),
                   a->split.c_str(), a->out.c_str());
    }
  });
}

}  // namespace csympnet::cli
