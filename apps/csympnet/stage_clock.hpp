// Where a fit's time goes: the wall and CPU seconds of each stage the identification announces
// (IdentifyHooks::stage), in order, for timings.json. A stage lasts until the next one starts or
// the clock is read. CPU seconds are the whole process's (every thread), so a stage that runs
// on two threads may show more CPU than wall seconds.
#pragma once

#include <chrono>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace csympnet::cli {

class StageClock {
 public:
  StageClock();
  // Ends the current stage (if any) and starts `name`.
  void enter(const std::string& name);
  // Ends the current stage; later calls to enter start new ones.
  void finish();
  // {"stages": [{"stage", "seconds", "cpu_seconds"}...], "by_stage": {name: {"seconds",
  // "cpu_seconds", "count"}}, "total_seconds", "total_cpu_seconds"}: the stages so far, the
  // one running included up to now.
  nlohmann::json report() const;

 private:
  struct Span {
    std::string name;
    double seconds = 0.0;
    double cpu_seconds = 0.0;
  };
  std::vector<Span> spans_;
  std::string current_;
  bool running_ = false;
  std::chrono::steady_clock::time_point start_wall_, began_wall_;
  double start_cpu_ = 0.0, began_cpu_ = 0.0;
};

// The process's CPU seconds so far (user + system, every thread).
double process_cpu_seconds();

}  // namespace csympnet::cli
