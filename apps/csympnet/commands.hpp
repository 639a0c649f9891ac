// The csympnet subcommands. Each add_* registers one subcommand on the app; its callback
// parses nothing itself and calls the library. No numerics live here.
#pragma once

#include <CLI/CLI.hpp>

namespace csympnet::cli {

void add_run(CLI::App& app);
void add_describe(CLI::App& app);
void add_generate(CLI::App& app);
void add_train(CLI::App& app);
void add_fit(CLI::App& app);
void add_evaluate(CLI::App& app);
void add_rollout(CLI::App& app);
void add_reproduce(CLI::App& app);

}  // namespace csympnet::cli
