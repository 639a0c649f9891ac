#include "csympnet/paper/outputs.hpp"

#include <cstdio>
#include <filesystem>

#include "csympnet/data/csv.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/models/model_file.hpp"

namespace csympnet {

std::string json_file_text(const nlohmann::json& doc) {
  return doc.dump(2) + "\n";
}

void write_json_file(const std::string& path, const nlohmann::json& doc) {
  write_text_atomic(path, json_file_text(doc));
}

OutputFiles run_output_files(const RunResult& r) {
  OutputFiles files;
  files.emplace_back("report.json", json_file_text(r.report));
  nlohmann::json meta = {{"system", r.report["config"]["preset"]["system"]},
                         {"preset", r.report["preset"]},
                         {"seed", r.report["seed"]},
                         {"train", r.report["config"]["train"]}};
  files.emplace_back("model.json", model_file_text(r.model, r.theta, meta));

  const auto& tests = r.data.test.trajectories;
  std::vector<Trajectory> predicted;
  predicted.reserve(tests.size());
  std::string energy = "traj,t,energy_pred,energy_ref\n";
  for (std::size_t m = 0; m < tests.size(); ++m) {
    predicted.push_back({tests[m].t, r.diagnostics.rollouts[m], {}});
    for (Index n = 0; n < tests[m].t.size(); ++n)
      energy += std::to_string(m) + "," + round_trip_text(tests[m].t(n)) + "," +
                round_trip_text(r.diagnostics.energy_pred[m](n)) + "," +
                round_trip_text(r.diagnostics.energy_ref[m](n)) + "\n";
  }
  files.emplace_back("rollout.csv", trajectories_csv_text(predicted));
  files.emplace_back("reference.csv", trajectories_csv_text(tests));
  files.emplace_back("energy.csv", std::move(energy));
  return files;
}

}  // namespace csympnet
