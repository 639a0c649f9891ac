// Files a run leaves in its output directory.
//
//   report.json     scalar results and the full configuration
//   model.json      the trained model (io/model_file.hpp)
//   rollout.csv     the learned rollouts, trajectories format (traj,t,q..,p..)
//   reference.csv   the reference test trajectories, same format
//   energy.csv      traj,t,energy_pred,energy_ref
#pragma once

#include <string>

#include "csympnet/io/files.hpp"
#include "csympnet/paper/run.hpp"

namespace csympnet {

// The files above, to be committed as one set (OutputDir::commit).
OutputFiles run_output_files(const RunResult& result);

// A JSON document as these files hold it: pretty-printed, with a final newline.
std::string json_file_text(const nlohmann::json& doc);

// Writes a JSON document atomically, pretty-printed.
void write_json_file(const std::string& path, const nlohmann::json& doc);

}  // namespace csympnet
