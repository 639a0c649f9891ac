// `reproduce`: run experiment suites (experiments/*.json), cache every run, write the
// summary, the tables and the figures.
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "commands.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/io/files.hpp"
#include "csympnet/paper/outputs.hpp"
#include "csympnet/paper/reproduce.hpp"
#include "csympnet/paper/summary.hpp"
#include "interrupt.hpp"
#include "system_options.hpp"

#ifndef CSYMPNET_SUITES_DIR
#define CSYMPNET_SUITES_DIR "experiments"
#endif
#ifndef CSYMPNET_FIGURES_SCRIPT
#define CSYMPNET_FIGURES_SCRIPT "experiments/figures.py"
#endif

namespace csympnet::cli {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const std::vector<std::string> kQuick = {"table2", "table3", "table4"};
const std::vector<std::string> kFull = {"table2", "table3",  "table4", "table5",
                                        "noise",  "samples", "hsweep", "reference"};
constexpr const char* kMarker = "reproduce.json";

struct Args {
  std::string suite = "quick", out, suites_dir;
  int jobs = 0;
  bool quiet = false, force = false, no_figures = false;
};

std::vector<std::string> suite_names(const std::string& arg) {
  if (arg == "quick") return kQuick;
  if (arg == "full") return kFull;
  std::vector<std::string> names;
  std::string item;
  for (std::size_t i = 0; i <= arg.size(); ++i) {
    if (i == arg.size() || arg[i] == ',') {
      require(!item.empty(), [&] {
        return "--suite '" + arg +
               "': empty name; expected quick, full or NAME[,NAME] (e.g. "
               "table2,noise)";
      });
      names.push_back(item);
      item.clear();
    } else {
      item += arg[i];
    }
  }
  return names;
}

std::string default_suites_dir() {
  if (const char* env = std::getenv("CSYMPNET_SUITES_DIR"); env && *env) return env;
  return CSYMPNET_SUITES_DIR;
}

// A reproduction directory may be resumed; any other non-empty directory needs --force.
// The marker is trusted by its content, not by its name: a user's own reproduce.json (or
// a damaged one) does not make a directory resumable, so its summary.json and timings.json
// are never overwritten without --force.
bool is_reproduce_marker(const fs::path& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return false;
  try {
    const json m = json::parse(read_text_file(path.string(), 1 << 20));
    return m.is_object() && m.value("format", "") == "csympnet-reproduce" && m.contains("suites") &&
           m["suites"].is_array();
  } catch (const std::exception&) {
    return false;
  }
}

OutputDir prepare_reproduce_dir(const std::string& out, bool force) {
  if (is_reproduce_marker(fs::path(out) / kMarker)) return OutputDir(out, /*force=*/true);
  return OutputDir(out, force);
}

std::string clock(double seconds) {
  char buf[32];
  const long s = std::lround(seconds);
  if (s >= 3600)
    std::snprintf(buf, sizeof buf, "%ldh%02ldm", s / 3600, (s / 60) % 60);
  else
    std::snprintf(buf, sizeof buf, "%ldm%02lds", s / 60, s % 60);
  return buf;
}

std::string python_interpreter() {
  if (const char* env = std::getenv("CSYMPNET_PYTHON"); env && *env) return env;
  return "/usr/bin/python3";
}

// The figures come from experiments/figures.py (matplotlib). The script is started with an
// argument vector (posix_spawn), never through a shell, so no character of --out can run as a
// command. Returns whether figures were drawn; a script that fails is an error.
bool draw_figures(const Args& a) {
  const char* env = std::getenv("CSYMPNET_FIGURES_SCRIPT");
  const std::string script = env && *env ? env : CSYMPNET_FIGURES_SCRIPT;
  const std::string py = python_interpreter();
  std::error_code ec;
  if (!fs::exists(script, ec) || !fs::exists(py, ec)) {
    std::fprintf(stderr, "reproduce: figures skipped (%s or %s not found)\n", script.c_str(),
                 py.c_str());
    return false;
  }
  std::vector<std::string> args = {py, script, a.out};
  std::vector<char*> argv;
  for (std::string& s : args) argv.push_back(s.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (a.quiet) posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  const int err = posix_spawn(&pid, py.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  require(err == 0, [&] {
    return "reproduce: could not start " + py + " " + script + ": " + std::strerror(err) +
           "; rerun with --no-figures to skip the figures";
  });
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    require(errno == EINTR, [&] {
      return std::string("reproduce: waiting for the figure script: ") + std::strerror(errno);
    });
  }
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return true;
  if (interrupted()) throw Interrupted("the figure script was stopped; the tables are in " + a.out);
  const std::string how = WIFEXITED(status) ? "exit " + std::to_string(WEXITSTATUS(status))
                                            : "signal " + std::to_string(WTERMSIG(status));
  throw Error("reproduce: the figure script " + script + " failed (" + how +
              "); the runs, summary and tables are written in " + a.out +
              "; rerun with --no-figures to skip the figures");
}

void print_table_overview(const json& summary, const std::vector<SuiteSpec>& suites) {
  for (const auto& s : suites) {
    if (s.kind != "table") continue;
    std::printf("%s:", s.name.c_str());
    for (const auto& preset : s.presets) {
      const json& c = summary.at("checks").at(s.name).at(preset);
      std::printf("  %s best L2 = %s", preset.c_str(),
                  c.at("best_l2_model").is_null()
                      ? "none"
                      : c.at("best_l2_model").get<std::string>().c_str());
    }
    std::printf("\n");
  }
}

void reproduce(const Args& a) {
  const RankInfo rank = rank_from_environment();
  std::vector<SuiteSpec> suites;
  std::vector<SuiteRun> runs;
  std::set<std::string> seen;
  for (const auto& name : suite_names(a.suite)) {
    const std::string path = (fs::path(a.suites_dir) / (name + ".json")).string();
    std::error_code ec;
    require(fs::exists(path, ec), [&] {
      return "--suite: no suite '" + name + "' (looked for " + path +
             "); expected quick, full, or names of files in " + a.suites_dir;
    });
    suites.push_back(load_suite(path));
    require(suites.back().name == name, [&] {
      return path + ": key 'name' = '" + suites.back().name + "', expected '" + name + "'";
    });
    for (auto& r : expand_suite(suites.back()))
      if (seen.insert(r.key).second) runs.push_back(std::move(r));
  }
  std::optional<OutputDir> out_dir;  // held by rank 0 for the whole reproduction
  if (rank.rank == 0) {
    out_dir.emplace(prepare_reproduce_dir(a.out, a.force));
    json marker = {{"format", "csympnet-reproduce"}, {"suites", json::array()}};
    for (const auto& s : suites) marker["suites"].push_back(s.name);
    write_json_file((fs::path(a.out) / kMarker).string(), marker);
  } else {
    // Rank 0 checks and marks the directory; the others create nothing until it has.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    std::error_code ec;
    while (!fs::exists(fs::path(a.out) / kMarker, ec)) {
      require(std::chrono::steady_clock::now() < deadline, [&] {
        return "rank " + std::to_string(rank.rank) + ": rank 0 did not prepare " + a.out +
               " within 120 s (is it refused? see rank 0's message)";
      });
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
  const std::string runs_dir = (fs::path(a.out) / "runs").string();
  const int jobs = a.jobs > 0 ? a.jobs : std::max(1u, std::thread::hardware_concurrency());
  const bool tty = !a.quiet && isatty(fileno(stderr));
  if (!a.quiet)
    std::fprintf(
        stderr, "reproduce: %zu runs in %zu suites, %d threads%s\n", runs.size(), suites.size(),
        jobs,
        rank.size > 1
            ? (", rank " + std::to_string(rank.rank) + " of " + std::to_string(rank.size)).c_str()
            : "");
  const ExecuteStats st = execute_runs(
      runs, runs_dir, jobs, rank,
      [&](const ExecuteProgress& p) {
        if (tty) {
          std::fprintf(stderr, "\r\033[Kreproduce: %zu/%zu runs (%zu cached) · %s · ETA %s · %s",
                       p.done + p.cached, p.total, p.cached, clock(p.seconds).c_str(),
                       clock(p.eta_seconds).c_str(), p.last.c_str());
          std::fflush(stderr);
        } else if (!a.quiet && (p.done * 20 / p.todo != (p.done - 1) * 20 / p.todo)) {
          // Not a terminal (a log file, CI): a line every 5% of the runs.
          std::fprintf(stderr, "reproduce: %zu/%zu runs (%zu cached), %s elapsed, ETA %s\n",
                       p.done + p.cached, p.total, p.cached, clock(p.seconds).c_str(),
                       clock(p.eta_seconds).c_str());
        }
      },
      [] { return interrupted(); });
  if (tty) std::fprintf(stderr, "\r\033[K");
  if (interrupted())
    throw Interrupted(std::to_string(st.executed) + " runs finished and cached in " + runs_dir +
                      " (" + std::to_string(st.cached) +
                      " were cached before); rerun the same command to resume");
  if (!a.quiet)
    std::fprintf(stderr, "reproduce: executed %zu runs (%zu failed), %zu cached, in %s\n",
                 st.executed, st.failed, st.cached, clock(st.seconds).c_str());

  // Whoever finds every record present writes the outputs; they are a pure function of the
  // records, so two ranks finishing together write identical files.
  std::map<std::string, json> records;
  for (const auto& r : runs)
    if (auto rec = load_record(runs_dir, r)) records.emplace(r.key, std::move(*rec));
  if (records.size() < runs.size()) {
    if (!a.quiet)
      std::fprintf(stderr,
                   "reproduce: %zu of %zu runs belong to other ranks and are not done "
                   "yet; the last rank to finish writes the summary\n",
                   runs.size() - records.size(), runs.size());
    return;
  }
  const RecordLookup lookup = [&](const SuiteRun& r) -> std::optional<json> {
    const auto it = records.find(r.key);
    if (it == records.end()) return std::nullopt;
    return it->second;
  };
  const json summary = summarize(suites, lookup);
  // The summary, the timings and every table change as one set (OutputDir::commit): a kill or
  // a full disk leaves the earlier complete set, never a summary beside older tables.
  OutputFiles files{{"summary.json", json_file_text(summary)},
                    {"timings.json", json_file_text(timings(suites, lookup))}};
  for (const auto& s : suites) {
    const TableFiles f = render_tables(s, summary);
    files.push_back({"tables/" + s.name + ".md", f.markdown});
    files.push_back({"tables/" + s.name + ".csv", f.csv});
    files.push_back({"tables/" + s.name + ".tex", f.latex});
  }
  if (out_dir)
    out_dir->commit(files);
  else
    commit_files(a.out, files);  // another rank: rank 0 holds the directory
  const bool figures = !a.no_figures && draw_figures(a);
  if (!a.quiet) {
    print_table_overview(summary, suites);
    std::printf("wrote %s/{summary.json,timings.json,tables/%s}\n", a.out.c_str(),
                figures ? ",figures/" : "");
  }
  if (st.failed > 0)
    throw Error(std::to_string(st.failed) + " run(s) failed; see \"error\" in " + runs_dir +
                "/*.json");
}

}  // namespace

void add_reproduce(CLI::App& app) {
  auto a = std::make_shared<Args>();
  a->suites_dir = default_suites_dir();
  CLI::App* cmd = app.add_subcommand(
      "reproduce", "Run the paper's experiment suites; write summary.json, tables and figures");
  cmd->add_option("--suite", a->suite,
                  "quick (Tables 2-4), full (everything) or NAME[,NAME] from --suites-dir");
  cmd->add_option("--out", a->out, "Output directory (an earlier reproduction is resumed)")
      ->required()
      ->check(kOutputPath);
  cmd->add_option("--jobs", a->jobs, "Threads (default: all cores)")
      ->check(kWholeNumber)
      ->check(in_range(1, 1024));
  cmd->add_option("--suites-dir", a->suites_dir, "Directory of suite files")
      ->check(kExistingDirectory);
  cmd->add_flag("--no-figures", a->no_figures, "Skip the matplotlib figures");
  cmd->add_flag("--force", a->force, "Allow a non-empty directory that is not a reproduction");
  cmd->add_flag("-q,--quiet", a->quiet, "No progress or summary");
  cmd->callback([a] {
    if (parse_only()) return;
    reproduce(*a);
  });
}

}  // namespace csympnet::cli
