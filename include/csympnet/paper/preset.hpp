// The paper's benchmark presets (docs/protocol.md, "Presets"): system, data sizes, steps and
// architectures.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/data/generate.hpp"
#include "csympnet/systems/system.hpp"
#include "csympnet/train/trainer.hpp"

namespace csympnet {

struct Preset {
  std::string name;  // "s1", "s2", "s3", "s2-100", "s3-100"
  SystemSpec system;
  Index n_train = 400;          // training pairs
  Index n_val = 100;            // validation pairs (N_train / 4)
  StepSpec train_steps;         // step of training and validation pairs
  double h_test = 0.2;          // step of the test rollouts
  double horizon = 10.0;        // test trajectories cover [0, horizon]
  Index n_test = 10;            // test trajectories M
  nlohmann::json core;          // symplectic core of CSympNet-ID and SympNet
  TrainOptions train;           // default recipe of CSympNet-ID and SympNet (docs/training.md)
  TrainOptions baseline_train;  // default recipe of the six other baselines (docs/baselines.md)
};
void to_json(nlohmann::json& j, const Preset& p);

std::vector<std::string> preset_names();
// Throws Error listing the valid names.
Preset preset_by_name(const std::string& name);

// The paper's recipe (docs/protocol.md, "Training"): AdamW lr 1e-3, weight decay 5e-4 on every
// parameter, constant rate, with the given epoch budget.
TrainOptions paper_recipe(long epochs);
// Names the recipe a TrainOptions amounts to: "paper" or "paper+<changes>".
std::string describe_recipe(const TrainOptions& t);

// Hyperparams JSON for make_model(): CSympNet-ID and SympNet get the preset's core, the
// baselines the protocol's MLP width for d. Throws Error listing valid names.
nlohmann::json model_spec_for(const Preset& p, const std::string& model);
// Width of the baselines' MLPs for d (32, 64 or 256).
int baseline_width(int d);
// The preset's default training options for `model`.
TrainOptions train_options_for(const Preset& p, const std::string& model);

}  // namespace csympnet
