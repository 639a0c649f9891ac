#include "fit_figure.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <vector>

#include "interrupt.hpp"

extern char** environ;

#ifndef CSYMPNET_PYTHON_EXECUTABLE
#define CSYMPNET_PYTHON_EXECUTABLE "/usr/bin/python3"
#endif
#ifndef CSYMPNET_BUILD_PYTHON_DIR
#define CSYMPNET_BUILD_PYTHON_DIR ""
#endif

namespace csympnet::cli {

namespace {

namespace fs = std::filesystem;

bool holds_package(const fs::path& dir) {
  std::error_code ec;
  return !dir.empty() && fs::is_regular_file(dir / "csympnet" / "fit_figure.py", ec);
}

// The directory to put first on PYTHONPATH, or "" for the interpreter's own path.
std::string package_dir() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec && holds_package(exe.parent_path().parent_path() / "python"))
    return (exe.parent_path().parent_path() / "python").string();
  if (holds_package(CSYMPNET_BUILD_PYTHON_DIR)) return CSYMPNET_BUILD_PYTHON_DIR;
  return "";
}

// The environment of the child: ours, with the package's directory first on PYTHONPATH.
std::vector<std::string> child_environment() {
  const std::string dir = package_dir();
  std::vector<std::string> env;
  std::string path = dir;
  for (char** e = environ; e != nullptr && *e != nullptr; ++e) {
    const std::string s = *e;
    if (s.rfind("PYTHONPATH=", 0) == 0) {
      const std::string old = s.substr(11);
      if (!old.empty()) path += (path.empty() ? "" : ":") + old;
    } else {
      env.push_back(s);
    }
  }
  if (!path.empty()) env.push_back("PYTHONPATH=" + path);
  return env;
}

// The last non-empty line of the child's standard error, without its "fit_figure: " prefix.
std::string last_line(const std::string& text) {
  std::size_t end = text.find_last_not_of(" \t\r\n");
  if (end == std::string::npos) return "";
  const std::size_t start = text.rfind('\n', end);
  std::string line = text.substr(start == std::string::npos ? 0 : start + 1,
                                 end + 1 - (start == std::string::npos ? 0 : start + 1));
  if (line.rfind("fit_figure: ", 0) == 0) line = line.substr(12);
  return line.size() > 400 ? line.substr(0, 397) + "..." : line;
}

}  // namespace

FigureOutcome draw_fit_figure(const std::string& out_dir) {
  const char* env_py = std::getenv("CSYMPNET_PYTHON");
  const std::string py = env_py != nullptr && *env_py != '\0' ? env_py : CSYMPNET_PYTHON_EXECUTABLE;
  if (::access(py.c_str(), X_OK) != 0)
    return {false, "no Python interpreter at " + py + " (" + std::strerror(errno) +
                       "; CSYMPNET_PYTHON names another)"};
  std::vector<std::string> args = {py, "-m", "csympnet.fit_figure", out_dir};
  std::vector<std::string> env = child_environment();
  std::vector<char*> argv, envp;
  for (std::string& s : args) argv.push_back(s.data());
  argv.push_back(nullptr);
  for (std::string& s : env) envp.push_back(s.data());
  envp.push_back(nullptr);

  int err_pipe[2];
  if (::pipe2(err_pipe, O_CLOEXEC) != 0)
    return {false, std::string("could not make a pipe: ") + std::strerror(errno)};
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_adddup2(&actions, err_pipe[1], STDERR_FILENO);
  pid_t pid = 0;
  const int spawned = posix_spawn(&pid, py.c_str(), &actions, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  ::close(err_pipe[1]);
  if (spawned != 0) {
    ::close(err_pipe[0]);
    return {false, "could not start " + py + ": " + std::strerror(spawned)};
  }

  // Read the child's standard error (the last 8 KiB kept) until the child has ended, polling
  // so that a signal is passed on within 0.1 s even when the child writes nothing. The child's
  // end, not the pipe's, ends the wait: a grandchild may hold the pipe open.
  using Clock = std::chrono::steady_clock;
  std::string err;
  bool forwarded = false, killed = false, ended = false, open = true;
  Clock::time_point forwarded_at;
  int status = 0;
  while (!ended) {
    if (interrupted() && !forwarded) {
      ::kill(pid, SIGINT);
      forwarded = true;
      forwarded_at = Clock::now();
    }
    if (forwarded && !killed && Clock::now() - forwarded_at > std::chrono::seconds(1)) {
      ::kill(pid, SIGKILL);
      killed = true;
    }
    pollfd p{err_pipe[0], POLLIN, 0};
    const int ready = open ? ::poll(&p, 1, 100) : 0;
    if (ready > 0) {
      char buf[4096];
      const ssize_t n = ::read(err_pipe[0], buf, sizeof buf);
      if (n > 0) {
        err.append(buf, static_cast<std::size_t>(n));
        if (err.size() > 8192) err.erase(0, err.size() - 8192);
        continue;  // read on while there is more
      }
      if (n == 0 || errno != EINTR) open = false;
    }
    const pid_t w = ::waitpid(pid, &status, WNOHANG);
    ended = w == pid || (w < 0 && errno != EINTR);
    if (!ended && !open) ::poll(nullptr, 0, 20);
  }
  // What the child wrote just before it ended.
  for (pollfd p{err_pipe[0], POLLIN, 0}; open && ::poll(&p, 1, 0) > 0;) {
    char buf[4096];
    const ssize_t n = ::read(err_pipe[0], buf, sizeof buf);
    if (n <= 0) break;
    err.append(buf, static_cast<std::size_t>(n));
  }
  if (err.size() > 8192) err.erase(0, err.size() - 8192);
  ::close(err_pipe[0]);
  if (WIFEXITED(status) && WEXITSTATUS(status) == 0) return {true, ""};
  if (interrupted()) return {false, "interrupted"};
  std::string why = last_line(err);
  if (why.empty())
    why = WIFEXITED(status)
              ? py + " -m csympnet.fit_figure exited with " + std::to_string(WEXITSTATUS(status))
              : py + " -m csympnet.fit_figure ended by signal " + std::to_string(WTERMSIG(status));
  return {false, why};
}

}  // namespace csympnet::cli
