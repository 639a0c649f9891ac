#include "csympnet/paper/preset.hpp"

#include <algorithm>
#include <cstdio>

#include "csympnet/core/error.hpp"
#include "csympnet/models/model.hpp"

namespace csympnet {

namespace {
// Epoch budgets and rates of the default recipe, measured in docs/training.md.
constexpr long kS1Epochs = 50000;
constexpr long kS2Epochs = 50000;
constexpr long kS3Epochs = 200000;
constexpr long kLargeEpochs = 3000;
constexpr double kS3LearningRate = 1e-2;
// The six baselines' budget (the paper gives none): see docs/baselines.md.
constexpr long kBaselineEpochs = 20000;
constexpr long kLargeBaselineEpochs = 3000;

// The paper's optimiser with a cosine-annealed rate (switch back with paper_recipe()).
TrainOptions improved_recipe(long epochs) {
  TrainOptions t = paper_recipe(epochs);
  t.lr_schedule = LrSchedule::kCosine;
  return t;
}

nlohmann::json la_core(int layers, int sublayers) {
  return {{"type", "la"}, {"layers", layers}, {"sublayers", sublayers}};
}
}  // namespace

void to_json(nlohmann::json& j, const Preset& p) {
  j = {{"name", p.name},
       {"system", p.system},
       {"n_train", p.n_train},
       {"n_val", p.n_val},
       {"train_steps", p.train_steps},
       {"h_test", p.h_test},
       {"horizon", p.horizon},
       {"n_test", p.n_test},
       {"core", p.core},
       {"train", p.train},
       {"baseline_train", p.baseline_train}};
}

std::vector<std::string> preset_names() {
  return {"s1", "s2", "s3", "s2-100", "s3-100"};
}

Preset preset_by_name(const std::string& name) {
  Preset p;
  p.name = name;
  if (name == "s1") {
    p.system = {"oscillator", 1, 0.05, 1.0, 1.0, 0.0};
    p.n_train = 80;
    p.n_val = 20;
    p.train_steps = {0.05, 0.15};
    p.core = la_core(5, 20);
    p.train = improved_recipe(kS1Epochs);
    p.baseline_train = improved_recipe(kBaselineEpochs);
  } else if (name == "s2" || name == "s2-100") {
    const bool big = name == "s2-100";
    p.system = {"chain", big ? 100 : 10, 0.05, 1.0, 1.0, 0.0};
    p.train_steps = {0.1, 0.1};
    p.core = big ? la_core(4, 4) : la_core(4, 10);
    p.train = improved_recipe(big ? kLargeEpochs : kS2Epochs);
    p.baseline_train = improved_recipe(big ? kLargeBaselineEpochs : kBaselineEpochs);
  } else if (name == "s3" || name == "s3-100") {
    const bool big = name == "s3-100";
    p.system = {"cubic", big ? 100 : 10, 0.05, 1.0, 1.0, big ? 1e-4 : 0.005};
    p.train_steps = {0.1, 0.1};
    p.core = big ? la_core(4, 4) : nlohmann::json{{"type", "g"}, {"layers", 7}, {"width", 50}};
    p.train = improved_recipe(big ? kLargeEpochs : kS3Epochs);
    p.baseline_train = improved_recipe(big ? kLargeBaselineEpochs : kBaselineEpochs);
    if (!big) p.train.adamw.lr = kS3LearningRate;
  } else {
    throw Error("unknown preset '" + name +
                "'; expected one of: " + comma_separated(preset_names()));
  }
  return p;
}

TrainOptions paper_recipe(long epochs) {
  TrainOptions t;
  t.epochs = epochs;
  t.adamw = AdamWOptions{};
  t.lr_schedule = LrSchedule::kConstant;
  return t;
}

std::string describe_recipe(const TrainOptions& t) {
  const AdamWOptions paper{};
  std::string changes;
  auto add = [&](const std::string& c) { changes += (changes.empty() ? "" : ",") + c; };
  if (t.lr_schedule != LrSchedule::kConstant) add(to_string(t.lr_schedule) + "-lr");
  auto num = [](double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", x);
    return std::string(buf);
  };
  if (t.adamw.lr != paper.lr) add("lr=" + num(t.adamw.lr));
  if (t.adamw.weight_decay != paper.weight_decay) add("wd=" + num(t.adamw.weight_decay));
  if (!t.adamw.decay_damping) add("no-beta-decay");
  if (t.adamw.beta1 != paper.beta1 || t.adamw.beta2 != paper.beta2 || t.adamw.eps != paper.eps)
    add("adam-constants");
  return changes.empty() ? "paper" : "paper+" + changes;
}

int baseline_width(int d) {
  // docs/protocol.md, "Baselines": 32 for d = 1, 64 for d = 10, 256 for d = 100; other
  // dimensions take the width of the nearest of those presets' classes.
  if (d <= 2) return 32;
  if (d <= 20) return 64;
  return 256;
}

nlohmann::json model_spec_for(const Preset& p, const std::string& model) {
  const auto types = model_types();
  require(std::find(types.begin(), types.end(), model) != types.end(), [&] {
    return "unknown model '" + model + "'; expected one of: " + comma_separated(types);
  });
  if (model == "csympnet" || model == "sympnet")
    return {{"type", model}, {"d", p.system.d}, {"core", p.core}};
  return {{"type", model}, {"d", p.system.d}, {"width", baseline_width(p.system.d)}};
}

TrainOptions train_options_for(const Preset& p, const std::string& model) {
  if (model == "csympnet" || model == "sympnet") return p.train;
  return p.baseline_train;
}

}  // namespace csympnet
