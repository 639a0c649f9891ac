// Files a run leaves in its output directory.
//
//   report.json     scalar results and the full configuration
//   model.json      the trained model (io/model_file.hpp)
//   rollout.csv     the learned rollouts, trajectories format (traj,t,q..,p..)
//   reference.csv   the reference test trajectories, same format
//   energy.csv      traj,t,energy_pred,energy_ref
#pragma once

#include <string>

#include "csympnet/experiments/run.hpp"

namespace csympnet {

void write_run_outputs(const std::string& dir, const RunResult& result);

// Writes a JSON document atomically, pretty-printed.
void write_json_file(const std::string& path, const nlohmann::json& doc);

}  // namespace csympnet
