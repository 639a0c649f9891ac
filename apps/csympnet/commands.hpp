// The csympnet subcommands. Each add_* registers one subcommand on the app; its callback
// parses nothing itself and calls the library. No numerics live here.
#pragma once

#include <string>

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
void add_kernels(CLI::App& app);

// One line on the SIMD kernels in use (cmd_kernels.cpp), printed after the version.
std::string kernels_summary();

// The whole command line: the app with every subcommand registered, as main() runs it.
void add_all_commands(CLI::App& app);

// Parse-only mode, for the command-line fuzz target (fuzz/fuzz_cli_args.cpp): every
// subcommand's callback returns before it touches a file or starts work, so parsing and the
// option validators run alone. Off in the CLI.
void set_parse_only(bool on);
bool parse_only();

}  // namespace csympnet::cli
