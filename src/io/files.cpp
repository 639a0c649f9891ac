#include "csympnet/io/files.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <system_error>

#include "csympnet/core/error.hpp"

namespace csympnet {

namespace fs = std::filesystem;

std::string read_text_file(const std::string& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (!fs::exists(st))
    throw Error("cannot read '" + path + "': no such file; expected an existing readable file");
  if (fs::is_directory(st))
    throw Error("cannot read '" + path + "': it is a directory; expected a regular file");
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw Error("cannot read '" + path + "': " + std::strerror(errno) +
                "; expected a readable file");
  std::ostringstream buf;
  buf << in.rdbuf();
  // An empty file makes operator<< set failbit without any real error, so only badbit counts.
  if (in.bad()) throw Error("cannot read '" + path + "': read error; expected a readable file");
  return std::move(buf).str();
}

namespace {

// A name no other writer (thread or process) can pick at the same moment; O_EXCL below
// guards against the rest.
fs::path temp_name_for(const fs::path& target) {
  static std::atomic<unsigned long> counter{0};
  const auto ticks = std::chrono::steady_clock::now().time_since_epoch().count();
  return target.parent_path() /
         ("." + target.filename().string() + ".tmp." + std::to_string(::getpid()) + "." +
          std::to_string(counter.fetch_add(1)) + "." + std::to_string(ticks));
}

bool write_all(int fd, const std::string& content) {
  const char* p = content.data();
  std::size_t left = content.size();
  while (left > 0) {
    const ssize_t n = ::write(fd, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    p += n;
    left -= static_cast<std::size_t>(n);
  }
  return true;
}

}  // namespace

void write_text_atomic(const std::string& path, const std::string& content) {
  const fs::path target(path);
  if (target.filename().empty())
    throw Error("cannot write '" + path + "': expected a file name, not a directory path");
  const fs::path tmp = temp_name_for(target);
  auto fail = [&](const std::string& why) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw Error("cannot write '" + path + "': " + why +
                "; expected a writable location in an existing directory");
  };

  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    // Nothing was created, so there is nothing to remove; report without touching tmp.
    throw Error("cannot write '" + path + "': " + std::strerror(errno) +
                "; expected a writable location in an existing directory");
  }
  const bool written = write_all(fd, content);
  const int write_errno = errno;
  // fsync before rename: otherwise a crash could leave the new name pointing at empty data.
  const bool synced = written && ::fsync(fd) == 0;
  const bool closed = ::close(fd) == 0;
  if (!written) fail(std::strerror(write_errno));
  if (!synced || !closed) fail(std::string("flush failed: ") + std::strerror(errno));

  std::error_code ec;
  fs::rename(tmp, target, ec);
  if (ec) fail("rename failed: " + ec.message());

  // Best effort: persist the directory entry too. Failure here does not undo the write.
  const fs::path dir = target.parent_path().empty() ? fs::path(".") : target.parent_path();
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    (void)::fsync(dfd);
    ::close(dfd);
  }
}

void prepare_output_dir(const std::string& dir, bool force) {
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (fs::exists(st)) {
    if (!fs::is_directory(st))
      throw Error("output directory '" + dir +
                  "' exists but is not a directory; expected a directory or a new path");
    const bool empty = fs::is_empty(dir, ec);
    if (ec)
      throw Error("cannot inspect output directory '" + dir + "': " + ec.message() +
                  "; expected a readable directory");
    if (!empty && !force)
      throw Error("output directory '" + dir +
                  "' is not empty and writing there would overwrite its contents; expected an "
                  "empty or new directory, or pass --force to write anyway");
    return;
  }
  fs::create_directories(dir, ec);
  if (ec)
    throw Error("cannot create output directory '" + dir + "': " + ec.message() +
                "; expected a path where directories can be created");
}

}  // namespace csympnet
