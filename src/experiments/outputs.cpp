#include "csympnet/experiments/outputs.hpp"

#include <cstdio>
#include <filesystem>

#include "csympnet/data/csv.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/io/model_file.hpp"

namespace csympnet {

void write_json_file(const std::string& path, const nlohmann::json& doc) {
  write_text_atomic(path, doc.dump(2) + "\n");
}

void write_run_outputs(const std::string& dir, const RunResult& r) {
  const std::filesystem::path base(dir);
  write_json_file((base / "report.json").string(), r.report);
  nlohmann::json meta = {{"system", r.report["config"]["preset"]["system"]},
                         {"preset", r.report["preset"]},
                         {"seed", r.report["seed"]},
                         {"train", r.report["config"]["train"]}};
  save_model((base / "model.json").string(), r.model, r.theta, meta);

  const auto& tests = r.data.test.trajectories;
  std::vector<Trajectory> predicted;
  predicted.reserve(tests.size());
  std::string energy = "traj,t,energy_pred,energy_ref\n";
  char buf[96];
  for (std::size_t m = 0; m < tests.size(); ++m) {
    predicted.push_back({tests[m].t, r.diagnostics.rollouts[m]});
    for (Index n = 0; n < tests[m].t.size(); ++n) {
      std::snprintf(buf, sizeof buf, "%zu,%.17g,%.17g,%.17g\n", m, tests[m].t(n),
                    r.diagnostics.energy_pred[m](n), r.diagnostics.energy_ref[m](n));
      energy += buf;
    }
  }
  write_trajectories_csv((base / "rollout.csv").string(), predicted);
  write_trajectories_csv((base / "reference.csv").string(), tests);
  write_text_atomic((base / "energy.csv").string(), energy);
}

}  // namespace csympnet
