#include "peer_export.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "bench_setup.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/data/csv.hpp"
#include "csympnet/train/adamw.hpp"
#include "csympnet/train/objective.hpp"

namespace csympnet::bench {

namespace {

// One number per line with 17 significant digits, which reads back bit-identical.
void write_numbers(const std::string& path, const std::vector<double>& values) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  require(f != nullptr, "cannot write " + path);
  for (const double v : values) std::fprintf(f, "%.17g\n", v);
  require(std::fclose(f) == 0, "cannot write " + path);
}

}  // namespace

void export_peer_inputs(const std::string& dir, const std::vector<std::string>& presets,
                        int epochs) {
  std::filesystem::create_directories(dir);
  for (const auto& preset : presets) {
    Setup s = make_setup(preset, "csympnet");
    const std::string base = dir + "/" + preset;
    write_pairs_csv(base + "-train.csv", s.train);
    std::ofstream(base + "-spec.json") << s.model.hyperparams().dump() << "\n";
    write_numbers(base + "-theta0.txt", {s.theta.data(), s.theta.data() + s.theta.size()});
    // The same loop as the epoch/P/csympnet benchmark and train_parameters().
    const Objective o = make_objective(s.model, s.train, s.val);
    AdamW opt(o.n_params, {}, o.damping_index);
    Vector grad(o.n_params);
    std::vector<double> losses;
    for (int e = 0; e < epochs; ++e) {
      losses.push_back(o.train_loss(s.theta, grad));
      opt.step(s.theta, grad);
    }
    write_numbers(base + "-losses.txt", losses);
  }
}

}  // namespace csympnet::bench
