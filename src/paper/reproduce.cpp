#include "csympnet/paper/reproduce.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <numeric>
#include <thread>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/diagnostics/learned_map.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/paper/outputs.hpp"

namespace csympnet {

namespace {

using nlohmann::json;

int env_int(const char* name, int fallback) {
  const char* v = std::getenv(name);
  if (v == nullptr || *v == '\0') return fallback;
  char* end = nullptr;
  const long x = std::strtol(v, &end, 10);
  require(end != nullptr && *end == '\0' && x >= 0 && x < 1000000, [&] {
    return std::string("environment variable ") + name + " = '" + v +
           "', expected a non-negative integer";
  });
  return static_cast<int>(x);
}

// Scalars only, plus the trajectory of the first test for the figures.
json diagnostics_record(const Diagnostics& d, double h_test) {
  json j = d;
  j["h_test"] = h_test;
  return j;
}

// Rows are states, (n+1) x 2d, as the figure code expects.
json rows_of(const Matrix& z) {
  json rows = json::array();
  for (Index n = 0; n < z.cols(); ++n) {
    std::vector<double> row(z.col(n).data(), z.col(n).data() + z.rows());
    rows.push_back(row);
  }
  return rows;
}

json first_trajectory(const Diagnostics& d, const Trajectory& ref) {
  const Vector& e_ref = d.energy_ref.front();
  const Vector& e_pred = d.energy_pred.front();
  return {{"t", std::vector<double>(ref.t.data(), ref.t.data() + ref.t.size())},
          {"reference", rows_of(ref.z)},
          {"prediction", rows_of(d.rollouts.front())},
          {"energy_ref", std::vector<double>(e_ref.data(), e_ref.data() + e_ref.size())},
          {"energy_pred", std::vector<double>(e_pred.data(), e_pred.data() + e_pred.size())}};
}

std::string record_path(const std::string& dir, const std::string& key) {
  return (std::filesystem::path(dir) / (key + ".json")).string();
}

}  // namespace

RankInfo rank_from_environment() {
  RankInfo r;
  r.rank = env_int("OMPI_COMM_WORLD_RANK", env_int("PMI_RANK", 0));
  r.size = env_int("OMPI_COMM_WORLD_SIZE", env_int("PMI_SIZE", 1));
  require(r.size >= 1 && r.rank < r.size, [&] {
    return "MPI environment gives rank " + std::to_string(r.rank) + " of size " +
           std::to_string(r.size) + ", expected 0 <= rank < size";
  });
  return r;
}

json execute_run(const SuiteRun& run, const std::function<bool()>& stop) {
  json rec = {{"key", run.key},
              {"config", run.config},
              {"h_tests", run.h_tests},
              {"extra_jacobians", run.extra_jacobians}};
  try {
    ProgressCallback keep_going;
    if (stop) keep_going = [&stop](const TrainProgress&) { return !stop(); };
    RunResult r = run_experiment(run.config, keep_going, /*evaluate_if_stopped=*/false, stop);
    if (r.training.stop_reason == StopReason::kCallback || r.refine.stopped) {
      rec["status"] = "interrupted";  // never cached: the run starts afresh next time
      return rec;
    }
    json report = r.report;
    report.erase("config");
    rec["status"] = "ok";
    rec["report"] = report;
    rec["trajectory"] = first_trajectory(r.diagnostics, r.data.test.trajectories.front());
    json by_h = json::array();
    by_h.push_back(diagnostics_record(r.diagnostics, run.h_tests.front()));
    const System sys(run.config.preset.system);
    LearnedMap map = learned_map(r.model, r.theta, run.config.ode);
    if (!run.extra_jacobians) map.jacobian = nullptr;
    for (std::size_t i = 1; i < run.h_tests.size(); ++i) {
      const double h = run.h_tests[i];
      Rng test_rng(run.config.test_seed, "test-trajectories");
      const TestSet tests =
          generate_test_set(sys, run.config.preset.n_test, h, run.config.preset.horizon, test_rng,
                            run.config.reference);
      by_h.push_back(diagnostics_record(evaluate(map, sys, tests.trajectories, h), h));
    }
    rec["by_h_test"] = by_h;
  } catch (const StopRequested&) {
    throw;  // a stop request is not a failure of the map
  } catch (const std::exception& e) {
    rec["status"] = "failed";
    rec["error"] = e.what();
  }
  return rec;
}

std::optional<json> load_record(const std::string& runs_dir, const SuiteRun& run) {
  const std::string path = record_path(runs_dir, run.key);
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return std::nullopt;
  try {
    json rec = json::parse(read_text_file(path));
    // The key hashes the config; comparing the config itself guards against collisions and
    // against records written by another version of the code.
    if (rec.value("key", "") != run.key || rec.value("config", json()) != json(run.config))
      return std::nullopt;
    return rec;
  } catch (const std::exception&) {
    return std::nullopt;  // unreadable (e.g. from a crashed writer of an old version): redo
  }
}

ExecuteStats execute_runs(const std::vector<SuiteRun>& runs, const std::string& runs_dir, int jobs,
                          RankInfo rank,
                          const std::function<void(const ExecuteProgress&)>& progress,
                          const std::function<bool()>& stop) {
  require(jobs >= 1, [&] { return "--jobs must be >= 1, got " + std::to_string(jobs); });
  std::filesystem::create_directories(runs_dir);
  const auto t0 = std::chrono::steady_clock::now();
  ExecuteStats stats;
  stats.total = runs.size();

  // Largest first, so the pool does not end waiting on one long run; the order and the rank
  // assignment depend on the run list alone.
  std::vector<std::size_t> order(runs.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return runs[a].cost > runs[b].cost; });
  std::vector<std::size_t> mine;
  double todo_cost = 0.0;
  for (std::size_t i = 0; i < order.size(); ++i) {
    const SuiteRun& run = runs[order[i]];
    if (load_record(runs_dir, run)) {
      ++stats.cached;
      continue;
    }
    if (static_cast<int>(i % static_cast<std::size_t>(rank.size)) != rank.rank) {
      ++stats.other_ranks;
      continue;
    }
    mine.push_back(order[i]);
    todo_cost += run.cost;
  }

  std::atomic<std::size_t> next{0};
  std::mutex mu;
  std::size_t done = 0, failed = 0;
  double done_cost = 0.0;
  std::exception_ptr fatal;
  auto worker = [&] {
    for (;;) {
      const std::size_t slot = next.fetch_add(1);
      if (slot >= mine.size()) return;
      const SuiteRun& run = runs[mine[slot]];
      if (stop && stop()) return;
      try {
        const json rec = execute_run(run, stop);
        if (rec["status"] == "interrupted") return;
        write_json_file(record_path(runs_dir, run.key), rec);
        std::lock_guard lock(mu);
        ++done;
        done_cost += run.cost;
        if (rec["status"] != "ok") ++failed;
        if (progress) {
          ExecuteProgress p;
          p.done = done;
          p.todo = mine.size();
          p.total = runs.size();
          p.cached = stats.cached;
          p.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          p.eta_seconds = done_cost > 0 ? p.seconds * (todo_cost - done_cost) / done_cost : 0.0;
          p.last = run.key;
          progress(p);
        }
      } catch (...) {  // a record could not be written: stop everyone, report it
        std::lock_guard lock(mu);
        if (!fatal) fatal = std::current_exception();
        next = mine.size();
        return;
      }
    }
  };
  const int n_threads = std::max(1, std::min<int>(jobs, static_cast<int>(mine.size())));
  {
    std::vector<std::jthread> pool;
    for (int i = 0; i < n_threads; ++i) pool.emplace_back(worker);
  }
  if (fatal) std::rethrow_exception(fatal);
  stats.executed = done;
  stats.failed = failed;
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return stats;
}

}  // namespace csympnet
