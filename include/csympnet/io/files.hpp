// Small file utilities: whole-file reads, crash-safe writes, and output-directory checks.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

namespace csympnet {

// The most bytes an input file may hold (1 GiB): far above any data set this tool trains on,
// far below what would exhaust memory once parsed.
inline constexpr std::size_t kMaxInputBytes = std::size_t{1} << 30;

// Returns the bytes of the file unchanged, read once (so a pipe or FIFO works); "-" reads
// standard input. Throws Error naming the path if it does not exist, is a directory, cannot be
// read (a signal interrupting the read included), or holds more than `max_bytes`. Reading
// stops after the first chunk holding a NUL byte: text never has one, and the callers' own
// checks then name its line.
std::string read_text_file(const std::string& path, std::size_t max_bytes = kMaxInputBytes);

// Writes `content` to a temporary file in the target's directory, flushes it to disk (fsync)
// and renames it over `path`, so readers see either the old file or the complete new one,
// never a half-written file. On failure the temporary is removed and Error names the path.
void write_text_atomic(const std::string& path, const std::string& content);

// Files to write together: names (NAME, or SUB/NAME for a file in a subdirectory, created if
// missing) relative to one directory, and their contents.
using OutputFiles = std::vector<std::pair<std::string, std::string>>;

// An output directory held by one writer for as long as this object lives.
//  - Created with missing parents if absent; an existing non-directory is refused.
//  - Exclusive: a lock file (`.csympnet.lock`, flock) is held, so a second csympnet writing
//    into the same directory at the same time is refused with the first one's pid, instead
//    of both "succeeding" and one result being lost. The kernel drops the lock when a
//    process dies, so a crash never leaves the directory locked.
//  - A commit (below) that a killed writer left half done is completed on taking it.
//  - An existing directory with anything in it is refused unless `force`, so a run never
//    silently overwrites an earlier one. The lock file and the temporary files a dead
//    writer left (".NAME.tmp.PID.N.T" whose PID is not running, see is_stale_temp) do not
//    count; the latter are removed once the directory is taken (empty, or `force`), never
//    by a refused command, which leaves the directory as it was.
//  - On release the lock file is removed, and a directory this object created is removed if
//    nothing was written into it (a failed run leaves no empty directory behind).
class [[nodiscard]] OutputDir {
 public:
  OutputDir(const std::string& dir, bool force);
  ~OutputDir();
  OutputDir(OutputDir&& other) noexcept;
  OutputDir(const OutputDir&) = delete;
  OutputDir& operator=(const OutputDir&) = delete;
  OutputDir& operator=(OutputDir&&) = delete;
  const std::string& path() const { return dir_; }

  // Writes a set of files (names in this directory → contents) as one change: every
  // file is first written complete and flushed under a temporary name (a full disk or any
  // failure leaves the old set as it was), then a journal naming them is written, then each
  // is renamed over its target and the journal removed. A process killed between the renames
  // leaves the journal; the next csympnet that takes the directory completes the renames
  // before anything else, so the directory holds the old complete set or the new one.
  void commit(const OutputFiles& files) const;

 private:
  void release() noexcept;
  std::string dir_;
  int fd_ = -1;
  bool created_ = false;
};

// OutputDir::commit without holding the directory: for a writer that knows no other writes
// there, or whose rivals write identical files (the ranks of one `reproduce`).
void commit_files(const std::string& dir, const OutputFiles& files);

// The usual way to take an output directory (see OutputDir).
OutputDir prepare_output_dir(const std::string& dir, bool force);

// The name of the lock file OutputDir keeps in a directory it holds.
inline constexpr const char* kOutputLockName = ".csympnet.lock";

// Throws Error naming `path` unless it names a regular file or nothing (lstat: a symbolic
// link is refused, not followed; so are directories, FIFOs, devices and sockets). Every atomic
// write checks its target with it: a rename would silently replace such a node with a regular
// file (turning /dev/null into a file, or a link into a copy).
void check_replaceable(const std::string& path);

// Throws Error if `path` holds a NUL byte (the system would read only the part before it).
void check_path_text(const std::string& path);

// True only for a temporary a dead csympnet writer left in `dir`: the name has the pattern
// below, the writer's pid in it is not a running process, and it is a regular file of ours.
// A name alone is no proof (a user's ".notes.tmp.1.2.3" is kept: pid 1 runs).
bool is_stale_temp(const std::string& dir, const std::string& filename);

// True for the name of a temporary file write_text_atomic makes (".NAME.tmp.PID.N.T").
bool is_atomic_write_temp(const std::string& filename);

}  // namespace csympnet
