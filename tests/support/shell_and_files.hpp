// For the tests that run the CLI as a user would: a command line's exit status, and a file's
// whole text.
#pragma once

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace csympnet::testing {

// The exit status of `cmd` run by the shell (128 when it did not exit normally). Tests only:
// the command is the test's own, never a user's string.
inline int shell(const std::string& cmd) {
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace csympnet::testing
