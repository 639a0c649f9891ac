#include "peer_export.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>

#include "bench_setup.hpp"
#include "csympnet/core/error.hpp"
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

// The pairs as raw little-endian float64, one row per pair: h, z0 (2d), z1 (2d). Text would
// take ~400 MB and minutes to parse at 40,000 pairs in d = 100; the bits are the same.
void write_pairs_binary(const std::string& path, const PairSet& pairs) {
  const Index dim = pairs.dim();
  std::vector<double> row(static_cast<std::size_t>(1 + 2 * dim));
  std::FILE* f = std::fopen(path.c_str(), "wb");
  require(f != nullptr, "cannot write " + path);
  bool ok = true;
  for (Index j = 0; j < pairs.size() && ok; ++j) {
    row[0] = pairs.h(j);
    for (Index i = 0; i < dim; ++i) {
      row[static_cast<std::size_t>(1 + i)] = pairs.z0(i, j);
      row[static_cast<std::size_t>(1 + dim + i)] = pairs.z1(i, j);
    }
    ok = std::fwrite(row.data(), sizeof(double), row.size(), f) == row.size();
  }
  require(std::fclose(f) == 0 && ok, "cannot write " + path);
}

}  // namespace

void export_peer_inputs(const std::string& dir, const std::vector<std::string>& presets,
                        int epochs) {
  std::filesystem::create_directories(dir);
  for (const auto& preset : presets) {
    Setup s = make_setup(preset, "csympnet");
    const std::string base = dir + "/" + preset;
    write_pairs_binary(base + "-train.f64", s.train);
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
