#include "csympnet/io/files.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>
#include <system_error>
#include <vector>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"

namespace csympnet {

namespace fs = std::filesystem;

std::string read_text_file(const std::string& path, std::size_t max_bytes) {
  const bool is_stdin = path == "-";
  const std::string name = is_stdin ? std::string("standard input ('-')") : "'" + path + "'";
  int fd = 0;
  if (!is_stdin) {
    check_path_text(path);
    std::error_code ec;
    const fs::file_status st = fs::status(path, ec);
    // status fails for more than a missing file: a loop of symbolic links (ELOOP), a
    // component that is a file (ENOTDIR), no permission to look (EACCES). Name those.
    if (ec && ec != std::errc::no_such_file_or_directory)
      throw Error("cannot read " + name + ": " + ec.message() +
                  "; expected an existing readable file");
    if (!fs::exists(st))
      throw Error("cannot read " + name + ": no such file; expected an existing readable file");
    if (fs::is_directory(st))
      throw Error("cannot read " + name + ": it is a directory; expected a regular file");
    // A FIFO's open waits for a writer; a signal (the CLI's handlers do not restart calls)
    // ends the wait with EINTR.
    fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0)
      throw Error("cannot read " + name + ": " + std::strerror(errno) +
                  "; expected a readable file");
  }
  std::string out;
  char buf[1 << 16];
  std::string failure;
  while (true) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0) {
      failure = std::strerror(errno);  // EINTR included: a signal stops the read
      break;
    }
    if (n == 0) break;
    if (stop_requested()) {  // a large file is read in seconds: stop between chunks
      failure = "reading stopped on request";
      break;
    }
    if (out.size() + static_cast<std::size_t>(n) > max_bytes) {
      failure =
          "it holds more than " + std::to_string(max_bytes) + " bytes, the most an input may hold";
      break;
    }
    out.append(buf, static_cast<std::size_t>(n));
    // A text input never holds a NUL byte: stop at the first one (the callers report it by
    // line), instead of reading a device like /dev/zero up to the size bound.
    if (std::memchr(buf, '\0', static_cast<std::size_t>(n)) != nullptr) break;
  }
  if (!is_stdin) ::close(fd);
  if (stop_requested()) throw StopRequested("reading " + name + " stopped on request");
  if (!failure.empty())
    throw Error("cannot read " + name + ": " + failure + "; expected a readable file");
  return out;
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

}  // namespace

void check_path_text(const std::string& path) {
  require(path.find('\0') == std::string::npos, [&] {
    return "path '" + printable(path.substr(0, 200)) +
           "' has an embedded null byte; expected a path without NUL characters";
  });
}

void check_replaceable(const std::string& path) {
  check_path_text(path);
  struct stat st {};
  // lstat: the name itself, not what a link points to. A failure other than "no such file"
  // (a component that is not a directory, no permission) is left to the write, which names it.
  if (::lstat(path.c_str(), &st) != 0) return;
  if (S_ISREG(st.st_mode)) return;
  const char* what = S_ISLNK(st.st_mode)    ? "a symbolic link (a rename would replace the link "
                                              "itself, not the file it points to)"
                     : S_ISDIR(st.st_mode)  ? "a directory"
                     : S_ISFIFO(st.st_mode) ? "a FIFO (named pipe)"
                     : S_ISCHR(st.st_mode)  ? "a character device"
                     : S_ISBLK(st.st_mode)  ? "a block device"
                     : S_ISSOCK(st.st_mode) ? "a socket"
                                            : "not a regular file";
  throw Error("cannot write '" + path + "': it is " + what +
              ", which csympnet never replaces; expected a regular file or a new path");
}

bool is_stale_temp(const std::string& dir, const std::string& name) {
  if (!is_atomic_write_temp(name)) return false;
  // The writer's pid is the first number after ".tmp.".
  const std::size_t at = name.rfind(".tmp.") + 5;
  const std::size_t dot = name.find('.', at);
  const std::string digits = name.substr(at, dot - at);
  if (digits.size() > 9) return false;  // not a pid this system could have made
  const long pid = std::stol(digits);
  if (pid <= 0 || pid == static_cast<long>(::getpid())) return false;
  // Alive (or not ours to signal): the writer may still be working on it.
  if (::kill(static_cast<pid_t>(pid), 0) == 0 || errno != ESRCH) return false;
  struct stat st {};
  return ::lstat((fs::path(dir) / name).c_str(), &st) == 0 && S_ISREG(st.st_mode) &&
         st.st_uid == ::geteuid();
}

namespace {

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

namespace {

// The content in a fresh temporary beside `target`, flushed to disk (fsync before any rename:
// otherwise a crash could leave the new name pointing at empty data). Returns its path; on
// failure nothing is left behind and Error names `target`.
fs::path write_synced_temp(const fs::path& target, const std::string& content) {
  const std::string path = target.string();
  if (target.filename().empty())
    throw Error("cannot write '" + path + "': expected a file name, not a directory path");
  check_replaceable(path);
  const fs::path tmp = temp_name_for(target);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) {
    // Nothing was created, so there is nothing to remove; report without touching tmp.
    throw Error("cannot write '" + path + "': " + std::strerror(errno) +
                "; expected a writable location in an existing directory");
  }
  const bool written = write_all(fd, content);
  const int write_errno = errno;
  const bool synced = written && ::fsync(fd) == 0;
  const bool closed = ::close(fd) == 0;
  if (!written || !synced || !closed) {
    const std::string why = !written ? std::strerror(write_errno)
                                     : std::string("flush failed: ") + std::strerror(errno);
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw Error("cannot write '" + path + "': " + why +
                "; expected a writable location in an existing directory");
  }
  return tmp;
}

// Best effort: persist the directory's entries too. Failure here does not undo a write.
void sync_directory(const fs::path& dir) {
  const fs::path d = dir.empty() ? fs::path(".") : dir;
  const int dfd = ::open(d.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    (void)::fsync(dfd);
    ::close(dfd);
  }
}

constexpr const char* kCommitJournal = ".csympnet.commit";

// A name OutputDir::commit accepts: NAME or SUB/NAME, each part a plain file name.
bool is_output_file_name(const std::string& name) {
  const std::size_t slash = name.find('/');
  auto plain = [](const std::string& part) {
    return !part.empty() && part != "." && part != ".." && part.find('/') == std::string::npos &&
           part.find('\0') == std::string::npos && part.find('\t') == std::string::npos &&
           part.find('\n') == std::string::npos;
  };
  if (slash == std::string::npos) return plain(name);
  return plain(name.substr(0, slash)) && plain(name.substr(slash + 1));
}

// Completes a commit a killed writer left: every temporary the journal names that still
// exists is renamed over its target, then the journal goes. Each journal line is
// "TEMP<TAB>TARGET", names inside `dir`.
void roll_forward(const fs::path& dir) {
  const fs::path journal = dir / kCommitJournal;
  std::error_code ec;
  if (!fs::exists(journal, ec)) return;
  std::istringstream lines(read_text_file(journal.string(), 1 << 20));
  for (std::string line; std::getline(lines, line);) {
    const std::size_t tab = line.find('\t');
    if (tab == std::string::npos) continue;
    const std::string tmp = line.substr(0, tab), target = line.substr(tab + 1);
    // Only names a commit could have written: a plain name or SUB/NAME on both sides, in the
    // same subdirectory, and our temp pattern.
    if (!is_output_file_name(target) || !is_output_file_name(tmp) ||
        fs::path(tmp).parent_path() != fs::path(target).parent_path() ||
        !is_atomic_write_temp(fs::path(tmp).filename().string()))
      continue;
    if (!fs::exists(dir / tmp, ec)) continue;  // renamed before the writer was killed
    // The same rule as a commit: only a regular file (or nothing) is replaced. On any failure
    // the journal stays, so the set can still be completed once the target is fixed.
    std::string why;
    try {
      check_replaceable((dir / target).string());
      fs::rename(dir / tmp, dir / target, ec);
      if (ec) why = ec.message();
    } catch (const Error& e) {
      why = e.what();
    }
    if (!why.empty())
      throw Error("cannot complete the set of files an interrupted csympnet left in '" +
                  dir.string() + "': renaming '" + tmp + "' over '" + target + "' failed (" + why +
                  "); the journal '" + kCommitJournal + "' is kept; expected '" + target +
                  "' to be a regular file or absent (move it away and run again)");
  }
  sync_directory(dir);
  fs::remove(journal, ec);
  sync_directory(dir);
}

}  // namespace

void write_text_atomic(const std::string& path, const std::string& content) {
  const fs::path target(path);
  const fs::path tmp = write_synced_temp(target, content);
  std::error_code ec;
  try {
    check_replaceable(path);  // again: the target may have changed while the data were written
  } catch (...) {
    fs::remove(tmp, ec);
    throw;
  }
  fs::rename(tmp, target, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw Error("cannot write '" + path + "': rename failed: " + ec.message() +
                "; expected a writable location in an existing directory");
  }
  sync_directory(target.parent_path());
}

void OutputDir::commit(const OutputFiles& files) const {
  require(fd_ >= 0, "OutputDir::commit: the directory is not held");
  commit_files(dir_, files);
}

void commit_files(const std::string& directory, const OutputFiles& files) {
  const fs::path dir(directory);
  std::vector<fs::path> temps;
  auto discard = [&] {
    std::error_code ignored;
    for (const fs::path& t : temps) fs::remove(t, ignored);
  };
  // 0. Every target replaceable (a regular file or absent) before anything is written: a
  //    directory or a FIFO where a result file belongs would fail its rename half way through
  //    the set.
  for (const auto& file : files) {  // not a structured binding: clang 14 cannot capture it
    const std::string& name = file.first;
    require(is_output_file_name(name), [&] {
      return "OutputDir::commit: '" + name + "' is not NAME or SUB/NAME of plain names";
    });
    check_replaceable((dir / name).string());
  }
  // 1. Every new file complete on disk, under a temporary name: a failure here (a full disk)
  //    leaves the old set untouched.
  std::string journal;
  try {
    for (const auto& [name, content] : files) {
      const fs::path sub = fs::path(name).parent_path();
      if (!sub.empty()) {
        std::error_code ec;
        fs::create_directories(dir / sub, ec);
        if (ec)
          throw Error("cannot create '" + (dir / sub).string() + "': " + ec.message() +
                      "; expected a writable output directory");
      }
      temps.push_back(write_synced_temp(dir / name, content));
      journal += (sub / temps.back().filename()).string() + "\t" + name + "\n";
    }
    // 2. The journal: from here on the new set is decided; a crash is rolled forward by the
    //    next csympnet that takes this directory.
    write_text_atomic((dir / kCommitJournal).string(), journal);
  } catch (...) {
    discard();
    throw;
  }
  // 3. The renames, then the journal goes.
  std::set<fs::path> subdirs;
  for (std::size_t k = 0; k < files.size(); ++k) {
    std::error_code ec;
    fs::rename(temps[k], dir / files[k].first, ec);
    if (ec)
      throw Error("cannot write '" + (dir / files[k].first).string() + "': rename failed: " +
                  ec.message() + "; the journal '" + std::string(kCommitJournal) +
                  "' is kept, and the next csympnet command on this directory completes the set "
                  "once the file can be replaced (expected a regular file or nothing there)");
    subdirs.insert(fs::path(files[k].first).parent_path());
  }
  for (const fs::path& sub : subdirs)
    if (!sub.empty()) sync_directory(dir / sub);
  sync_directory(dir);
  std::error_code ec;
  fs::remove(dir / kCommitJournal, ec);
  sync_directory(dir);
}

bool is_atomic_write_temp(const std::string& name) {
  // "." NAME ".tmp." PID "." COUNTER "." TICKS, the three numbers all digits.
  if (name.size() < 2 || name[0] != '.') return false;
  const std::size_t at = name.rfind(".tmp.");
  if (at == std::string::npos || at < 2) return false;
  int fields = 0;
  std::size_t digits = 0;
  for (std::size_t i = at + 5; i <= name.size(); ++i) {
    if (i == name.size() || name[i] == '.') {
      if (digits == 0) return false;
      ++fields;
      digits = 0;
    } else if (name[i] >= '0' && name[i] <= '9') {
      ++digits;
    } else {
      return false;
    }
  }
  return fields == 3;
}

namespace {

std::string read_lock_owner(int fd) {
  char buf[32] = {};
  const ssize_t n = ::pread(fd, buf, sizeof buf - 1, 0);
  std::string s = n > 0 ? std::string(buf, static_cast<std::size_t>(n)) : std::string();
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s.empty() ? "unknown" : s;
}

}  // namespace

OutputDir::OutputDir(const std::string& dir, bool force) : dir_(dir) {
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (fs::exists(st) && !fs::is_directory(st))
    throw Error("output directory '" + dir +
                "' exists but is not a directory; expected a directory or a new path");
  if (!fs::exists(st)) {
    created_ = fs::create_directories(dir, ec);
    if (ec)
      throw Error("cannot create output directory '" + dir + "': " + ec.message() +
                  "; expected a path where directories can be created");
  }
  const fs::path lock = fs::path(dir) / kOutputLockName;
  // Lock, then check that the name still refers to the file locked: a writer that finishes
  // unlinks its lock file, and a lock on an unlinked file protects nothing.
  for (int attempt = 0;; ++attempt) {
    fd_ = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (fd_ < 0) {
      const std::string why = std::strerror(errno);
      release();
      throw Error("cannot create the lock file '" + lock.string() + "': " + why +
                  "; expected a writable output directory");
    }
    if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      const std::string owner = read_lock_owner(fd_);
      ::close(fd_);
      fd_ = -1;
      created_ = false;  // the other writer's directory now
      throw Error("output directory '" + dir + "' is being written by another csympnet (pid " +
                  owner + "); expected a directory no other run is writing to");
    }
    struct stat held {
    }, named{};
    if (::fstat(fd_, &held) == 0 && ::stat(lock.c_str(), &named) == 0 &&
        held.st_ino == named.st_ino && held.st_dev == named.st_dev)
      break;
    ::close(fd_);
    fd_ = -1;
    if (attempt >= 100) {
      release();
      throw Error("cannot lock output directory '" + dir +
                  "': its lock file keeps changing; expected one writer at a time");
    }
  }
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, pid.data(), pid.size(), 0) < 0) {
    // The pid is only a courtesy for the message of a refused second writer.
  }
  // A commit a killed writer left half done is completed first (its temporaries are in the
  // journal), then what is there besides our lock and stale temporaries (removed)?
  try {
    roll_forward(fs::path(dir));
  } catch (...) {
    created_ = false;
    release();
    throw;
  }
  // What is there besides our lock and the temporaries of writers proven dead? Nothing is
  // removed while this is decided (a refusal must leave the directory as it was).
  bool empty = true;
  std::vector<fs::path> stale;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name == kOutputLockName) continue;
    if (is_stale_temp(dir, name)) {
      stale.push_back(it->path());
      continue;
    }
    empty = false;
  }
  if (ec) {
    const std::string why = ec.message();
    release();
    throw Error("cannot inspect output directory '" + dir + "': " + why +
                "; expected a readable directory");
  }
  if (!empty && !force) {
    release();
    throw Error("output directory '" + dir +
                "' is not empty and writing there would overwrite its contents; expected an "
                "empty or new directory, or pass --force to write anyway");
  }
  // The command writes here: now the dead writers' temporaries go.
  for (const fs::path& p : stale) {
    std::error_code ignored;
    fs::remove(p, ignored);
  }
}

OutputDir::OutputDir(OutputDir&& other) noexcept
    : dir_(std::move(other.dir_)), fd_(other.fd_), created_(other.created_) {
  other.fd_ = -1;
  other.created_ = false;
}

OutputDir::~OutputDir() {
  release();
}

void OutputDir::release() noexcept {
  std::error_code ec;
  if (fd_ >= 0) {
    fs::remove(fs::path(dir_) / kOutputLockName, ec);  // unlink while still holding the lock
    ::close(fd_);
    fd_ = -1;
  }
  if (created_ && fs::is_empty(dir_, ec) && !ec) fs::remove(dir_, ec);
  created_ = false;
}

OutputDir prepare_output_dir(const std::string& dir, bool force) {
  return OutputDir(dir, force);
}

}  // namespace csympnet
