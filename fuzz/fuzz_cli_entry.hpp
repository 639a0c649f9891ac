// Fuzz entry points that need more than the parsers of fuzz_entry.hpp: the command line
// (CLI11 and every option validator of every subcommand) and the suite files `reproduce`
// reads. Shared, like fuzz_entry.hpp, by the libFuzzer targets and the replay test.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "commands.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/paper/suite.hpp"
#include "fuzz_entry.hpp"

namespace csympnet::fuzz {

// The bytes are the arguments after the program name, separated by NUL bytes (at most 64).
// The subcommands run in parse-only mode, so nothing is read, written or trained. A parse
// ends in success, a CLI::ParseError (a usage error, or --help/--version) or csympnet::Error;
// anything else escapes and is a finding.
inline int cli_args(const std::uint8_t* data, std::size_t size) {
  std::vector<std::string> args{"csympnet"};
  std::string current;
  for (std::size_t i = 0; i < size && args.size() <= 64; ++i) {
    if (data[i] == 0) {
      args.push_back(current);
      current.clear();
    } else {
      current += static_cast<char>(data[i]);
    }
  }
  if (args.size() <= 64) args.push_back(current);
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);

  cli::set_parse_only(true);
  CLI::App app{"csympnet"};
  cli::add_all_commands(app);
  try {
    app.parse(static_cast<int>(args.size()), argv.data());
  } catch (const CLI::ParseError&) {
  } catch (const Error&) {
  }
  return 0;
}

// An accepted suite expands to runs with valid configurations, distinct keys and at least one
// evaluation step each, in the same order every time.
inline int suite_file(const std::uint8_t* data, std::size_t size) {
  SuiteSpec s;
  try {
    s = suite_from_text(std::string(reinterpret_cast<const char*>(data), size), "fuzz.json");
  } catch (const Error&) {
    return 0;
  }
  std::vector<SuiteRun> runs;
  try {
    runs = expand_suite(s);
  } catch (const Error&) {
    return 0;  // e.g. a model that cannot be built for a preset
  }
  std::vector<std::string> keys;
  for (const SuiteRun& r : runs) {
    if (r.h_tests.empty()) contract_broken("a run without an evaluation step");
    try {
      r.config.validate();
    } catch (const Error&) {
      contract_broken("an expanded run has an invalid configuration");
    }
    keys.push_back(r.key);
  }
  std::sort(keys.begin(), keys.end());
  if (std::adjacent_find(keys.begin(), keys.end()) != keys.end())
    contract_broken("two runs of a suite share a cache key");
  const std::vector<SuiteRun> again = expand_suite(s);
  if (again.size() != runs.size()) contract_broken("expansion is not deterministic");
  for (std::size_t k = 0; k < runs.size(); ++k)
    if (again[k].key != runs[k].key) contract_broken("expansion is not deterministic");
  return 0;
}

}  // namespace csympnet::fuzz
