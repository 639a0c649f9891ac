// The command line as a whole: every subcommand on one app, and the parse-only switch that
// the command-line fuzz target uses.
#include "commands.hpp"

#include <atomic>

#include "kernels/registry.hpp"

namespace csympnet::cli {

namespace {
std::atomic<bool> g_parse_only{false};
}  // namespace

void set_parse_only(bool on) {
  g_parse_only.store(on);
}
bool parse_only() {
  return g_parse_only.load();
}

void add_all_commands(CLI::App& app) {
  app.require_subcommand(1);
  app.set_version_flag("--version",
                       [] { return "csympnet " CSYMPNET_VERSION "\n" + kernels_summary(); });
  add_run(app);
  add_describe(app);
  add_generate(app);
  add_train(app);
  add_fit(app);
  add_evaluate(app);
  add_rollout(app);
  add_reproduce(app);
  add_kernels(app);
  // A bad CSYMPNET_ARITHMETIC stops every command before it starts work (--arithmetic, parsed
  // by then, overrides the variable and keeps it unread).
  app.parse_complete_callback([] {
    (void)kernels::arithmetic();
    kernels::check_kernels_environment();
  });
}

}  // namespace csympnet::cli
