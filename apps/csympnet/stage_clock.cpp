#include "stage_clock.hpp"

#include <ctime>
#include <map>

namespace csympnet::cli {

double process_cpu_seconds() {
  timespec ts{};
  if (clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts) != 0) return 0.0;
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

StageClock::StageClock()
    : began_wall_(std::chrono::steady_clock::now()), began_cpu_(process_cpu_seconds()) {}

void StageClock::finish() {
  if (!running_) return;
  const auto now = std::chrono::steady_clock::now();
  spans_.push_back({current_, std::chrono::duration<double>(now - start_wall_).count(),
                    process_cpu_seconds() - start_cpu_});
  running_ = false;
}

void StageClock::enter(const std::string& name) {
  finish();
  current_ = name;
  running_ = true;
  start_wall_ = std::chrono::steady_clock::now();
  start_cpu_ = process_cpu_seconds();
}

nlohmann::json StageClock::report() const {
  std::vector<Span> spans = spans_;
  const auto now = std::chrono::steady_clock::now();
  const double cpu_now = process_cpu_seconds();
  if (running_)
    spans.push_back(
        {current_, std::chrono::duration<double>(now - start_wall_).count(), cpu_now - start_cpu_});
  nlohmann::json list = nlohmann::json::array();
  std::map<std::string, nlohmann::json> by;
  for (const Span& s : spans) {
    list.push_back({{"stage", s.name}, {"seconds", s.seconds}, {"cpu_seconds", s.cpu_seconds}});
    nlohmann::json& b = by[s.name];
    if (b.is_null()) b = {{"seconds", 0.0}, {"cpu_seconds", 0.0}, {"count", 0}};
    b["seconds"] = b["seconds"].get<double>() + s.seconds;
    b["cpu_seconds"] = b["cpu_seconds"].get<double>() + s.cpu_seconds;
    b["count"] = b["count"].get<int>() + 1;
  }
  return {{"stages", list},
          {"by_stage", nlohmann::json(by)},
          {"total_seconds", std::chrono::duration<double>(now - began_wall_).count()},
          {"total_cpu_seconds", cpu_now - began_cpu_}};
}

}  // namespace csympnet::cli
