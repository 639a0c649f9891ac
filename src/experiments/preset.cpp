#include "csympnet/experiments/preset.hpp"

#include "csympnet/core/error.hpp"

namespace csympnet {

namespace {
std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

nlohmann::json la_core(int layers, int sublayers) {
  return {{"type", "la"}, {"layers", layers}, {"sublayers", sublayers}};
}
}  // namespace

void to_json(nlohmann::json& j, const Preset& p) {
  j = {{"name", p.name},       {"system", p.system},           {"n_train", p.n_train},
       {"n_val", p.n_val},     {"train_steps", p.train_steps}, {"h_test", p.h_test},
       {"horizon", p.horizon}, {"n_test", p.n_test},           {"core", p.core},
       {"epochs", p.epochs}};
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
    p.epochs = 20000;
  } else if (name == "s2" || name == "s2-100") {
    const bool big = name == "s2-100";
    p.system = {"chain", big ? 100 : 10, 0.05, 1.0, 1.0, 0.0};
    p.train_steps = {0.1, 0.1};
    p.core = big ? la_core(4, 4) : la_core(4, 10);
    p.epochs = big ? 3000 : 20000;
  } else if (name == "s3" || name == "s3-100") {
    const bool big = name == "s3-100";
    p.system = {"cubic", big ? 100 : 10, 0.05, 1.0, 1.0, big ? 1e-4 : 0.005};
    p.train_steps = {0.1, 0.1};
    p.core = big ? la_core(4, 4) : nlohmann::json{{"type", "g"}, {"layers", 7}, {"width", 50}};
    p.epochs = big ? 3000 : 20000;
  } else {
    throw Error("unknown preset '" + name + "'; expected one of: " + join(preset_names()));
  }
  return p;
}

std::vector<std::string> map_model_names() {
  return {"csympnet", "sympnet"};
}

nlohmann::json model_spec_for(const Preset& p, const std::string& model) {
  bool known = false;
  for (const auto& m : map_model_names()) known = known || m == model;
  require(known, "unknown model '" + model + "'; expected one of: " + join(map_model_names()));
  nlohmann::json spec = {{"type", model}, {"d", p.system.d}, {"core", p.core}};
  return spec;
}

}  // namespace csympnet
