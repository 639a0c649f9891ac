// Executing suites: every run is independent and cached as DIR/runs/KEY.json the moment it
// finishes (atomic write), so an interrupted reproduction resumes where it stopped and a
// finished run is never repeated. Runs spread over a thread pool and, under mpirun, over
// ranks (runs i with i mod size = rank); a run's record depends on its config alone, so the
// records — and every table built from them — are identical however the work was divided.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "csympnet/paper/suite.hpp"

namespace csympnet {

// This process's place among MPI ranks, read from the launcher's environment
// (OMPI_COMM_WORLD_RANK/SIZE, PMI_RANK/SIZE); {0, 1} outside mpirun.
struct RankInfo {
  int rank = 0;
  int size = 1;
};
RankInfo rank_from_environment();

// The cached record of one run: its key and config, the report's scalars, the diagnostics
// at every h_test, and the first test trajectory (reference and predicted states, (n+1) x 2d,
// and the energies) for the trajectory figures.
// When `stop` turns true during training, the run ends early and comes back with "status":
// "interrupted"; such a record is never cached.
nlohmann::json execute_run(const SuiteRun& run, const std::function<bool()>& stop = {});

// The record cached for `run` in runs_dir, if present and made from the same config.
std::optional<nlohmann::json> load_record(const std::string& runs_dir, const SuiteRun& run);

struct ExecuteProgress {
  std::size_t done = 0;   // runs finished by this process (executed now)
  std::size_t todo = 0;   // runs this process had to execute
  std::size_t total = 0;  // runs of all ranks, cached ones included
  std::size_t cached = 0;
  double seconds = 0.0;
  double eta_seconds = 0.0;  // from the cost model, scaled by the measured rate
  std::string last;          // key of the run that just finished
};

struct ExecuteStats {
  std::size_t total = 0, cached = 0, executed = 0, failed = 0, other_ranks = 0;
  double seconds = 0.0;
};

// Runs every run assigned to `rank` that is not cached yet, with `jobs` threads, writing each
// record as it finishes. A run that throws is recorded with "status": "failed" and its message.
// Once `stop` returns true no run starts and the runs in flight end without a record, so a
// later call redoes exactly those (stats.executed counts recorded runs only).
ExecuteStats execute_runs(const std::vector<SuiteRun>& runs, const std::string& runs_dir, int jobs,
                          RankInfo rank,
                          const std::function<void(const ExecuteProgress&)>& progress = {},
                          const std::function<bool()>& stop = {});

}  // namespace csympnet
