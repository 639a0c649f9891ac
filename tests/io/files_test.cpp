#include "csympnet/io/files.hpp"

#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <optional>

#include <csignal>
#include <filesystem>
#include <iterator>

#include "../data/temp_dir.hpp"
#include "csympnet/core/error.hpp"

namespace csympnet {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

std::size_t entries(const fs::path& dir) {
  return static_cast<std::size_t>(std::distance(fs::directory_iterator(dir), {}));
}

TEST(ReadTextFile, ReturnsBytesAndNamesMissingPath) {
  TempDir dir;
  const std::string bytes("a\0b\r\n", 5);
  EXPECT_EQ(read_text_file(dir.write("x.bin", bytes)), bytes);
  EXPECT_EQ(read_text_file(dir.write("empty", "")), "");
  try {
    read_text_file(dir.file("missing.txt"));
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(dir.file("missing.txt")), std::string::npos);
  }
  EXPECT_THROW(read_text_file(dir.path().string()), Error);
}

TEST(WriteTextAtomic, ReplacesContentAndLeavesNoTempFiles) {
  TempDir dir;
  const std::string path = dir.file("out.txt");
  write_text_atomic(path, "first");
  write_text_atomic(path, std::string(1 << 20, 'z'));
  write_text_atomic(path, "second\n");
  EXPECT_EQ(read_text_file(path), "second\n");
  EXPECT_EQ(entries(dir.path()), 1u);
}

TEST(WriteTextAtomic, FailureNamesPathAndLeavesNothingBehind) {
  TempDir dir;
  const std::string bad = dir.file("no/such/dir/out.txt");
  try {
    write_text_atomic(bad, "x");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
  }
  // A directory in the way makes the rename fail after the temp file was written.
  fs::create_directory(dir.file("taken"));
  fs::create_directory(dir.file("taken/inner"));
  EXPECT_THROW(write_text_atomic(dir.file("taken"), "x"), Error);
  EXPECT_EQ(entries(dir.path()), 1u);
  EXPECT_TRUE(fs::is_directory(dir.file("taken")));
}

TEST(ReadTextFile, RefusesWhatExceedsTheBoundAndStopsAtANul) {
  TempDir dir;
  const std::string big = dir.write("big.csv", std::string(1000, 'x'));
  EXPECT_EQ(read_text_file(big, 1000).size(), 1000u);
  try {
    (void)read_text_file(big, 999);
    FAIL();
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(big), std::string::npos) << msg;
    EXPECT_NE(msg.find("more than 999 bytes"), std::string::npos) << msg;
  }
  // /dev/zero is endless: the read stops at the first chunk, which holds NUL bytes.
  const std::string zeros = read_text_file("/dev/zero");
  EXPECT_GT(zeros.size(), 0u);
  EXPECT_LE(zeros.size(), std::size_t{1} << 16);
  EXPECT_THROW((void)read_text_file(dir.file("missing")), Error);
  EXPECT_THROW((void)read_text_file(dir.path().string()), Error);
}

TEST(PrepareOutputDir, CreatesMissingAcceptsEmptyAndRemovesWhatItCreatedIfLeftEmpty) {
  TempDir dir;
  const std::string nested = dir.file("a/b/c");
  {
    const OutputDir held = prepare_output_dir(nested, false);
    EXPECT_TRUE(fs::is_directory(nested));
    EXPECT_TRUE(fs::exists(fs::path(nested) / kOutputLockName));
  }
  // Created here and nothing written: a failed run leaves no empty directory behind.
  EXPECT_FALSE(fs::exists(nested));
  EXPECT_TRUE(fs::is_directory(dir.file("a/b")));
  // An existing empty directory is accepted, kept, and left without the lock file.
  fs::create_directories(nested);
  { const OutputDir held = prepare_output_dir(nested, false); }
  EXPECT_TRUE(fs::is_directory(nested));
  EXPECT_TRUE(fs::is_empty(nested));
  // What a run wrote keeps a directory it created.
  {
    const OutputDir held = prepare_output_dir(dir.file("new"), false);
    write_text_atomic(dir.file("new/result.json"), "{}");
  }
  EXPECT_EQ(read_text_file(dir.file("new/result.json")), "{}");
  EXPECT_EQ(entries(dir.file("new")), 1u);
}

TEST(PrepareOutputDir, RefusesNonEmptyWithoutForce) {
  TempDir dir;
  const std::string out = dir.file("run");
  {
    const OutputDir held = prepare_output_dir(out, false);
    write_text_atomic(out + "/result.json", "{}");
  }
  try {
    const OutputDir held = prepare_output_dir(out, false);
    FAIL();
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(out), std::string::npos) << msg;
    EXPECT_NE(msg.find("overwrite"), std::string::npos) << msg;
    EXPECT_NE(msg.find("--force"), std::string::npos) << msg;
  }
  EXPECT_NO_THROW({ const OutputDir held = prepare_output_dir(out, true); });
  EXPECT_EQ(read_text_file(out + "/result.json"), "{}");  // force does not delete anything
  // A user's hidden file counts: it is theirs.
  const std::string other = dir.file("other");
  fs::create_directories(other);
  write_text_atomic(other + "/.notes", "mine");
  EXPECT_THROW({ const OutputDir held = prepare_output_dir(other, false); }, Error);
}

// Two writers into one directory: the second is refused with the first one's pid, even with
// --force, and the directory is free again once the first lets go. (flock conflicts between
// two open file descriptions in one process as between processes.)
TEST(PrepareOutputDir, OneWriterAtATime) {
  TempDir dir;
  const std::string out = dir.file("shared");
  std::optional<OutputDir> first(prepare_output_dir(out, false));
  for (const bool force : {false, true}) {
    try {
      const OutputDir second = prepare_output_dir(out, force);
      FAIL() << "a second writer was let in";
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("being written by another csympnet (pid " + std::to_string(::getpid())),
                std::string::npos)
          << msg;
      EXPECT_NE(msg.find(out), std::string::npos) << msg;
    }
  }
  EXPECT_TRUE(fs::is_directory(out));  // the refused writer did not remove the first's directory
  write_text_atomic(out + "/result.json", "{}");
  first.reset();
  EXPECT_FALSE(fs::exists(fs::path(out) / kOutputLockName));
  EXPECT_NO_THROW({ const OutputDir again = prepare_output_dir(out, true); });
}

// Temporary files a dead writer left do not make a directory "not empty" (ls shows
// nothing), and are removed after the next commit, not before; only names of
// write_text_atomic's exact pattern whose writer's pid is not running count as such.
TEST(PrepareOutputDir, StaleTemporariesAreRemovedNotCounted) {
  EXPECT_TRUE(is_atomic_write_temp(".report.json.tmp.123.0.456789"));
  EXPECT_TRUE(is_atomic_write_temp(".a.tmp.1.2.3"));
  for (const char* name :
       {"report.json", ".report.json", ".report.json.tmp.", ".x.tmp.1.2", ".x.tmp.1.2.3.4",
        ".x.tmp.1.a.3", ".x.tmp.1..3", "x.tmp.1.2.3", ".tmp.1.2.3"})
    EXPECT_FALSE(is_atomic_write_temp(name)) << name;
  TempDir dir;
  const std::string out = dir.file("killed");
  fs::create_directories(out);
  const pid_t dead = ::fork();  // a pid that surely runs no writer any more
  if (dead == 0) ::_exit(0);
  ::waitpid(dead, nullptr, 0);
  const std::string pid = std::to_string(dead);
  write_text_atomic(out + "/.report.json.tmp." + pid + ".0.99", "half");
  write_text_atomic(out + "/.model.json.tmp." + pid + ".1.100", "half");
  EXPECT_TRUE(is_stale_temp(out, ".report.json.tmp." + pid + ".0.99"));
  EXPECT_FALSE(is_stale_temp(out, ".report.json.tmp.1.0.99"));  // pid 1 runs
  EXPECT_FALSE(is_stale_temp(out, ".x.tmp." + std::to_string(::getpid()) + ".0.1"));
  // A refused taking removes nothing ...
  write_text_atomic(out + "/notes.txt", "mine");
  EXPECT_THROW({ const OutputDir held = prepare_output_dir(out, false); }, Error);
  EXPECT_EQ(std::distance(fs::directory_iterator(out), fs::directory_iterator()), 3);
  fs::remove(fs::path(out) / "notes.txt");
  // ... a directory holding only dead writers' temporaries counts as empty, and taking it
  // removes them.
  { const OutputDir held = prepare_output_dir(out, false); }
  EXPECT_TRUE(fs::is_empty(out));
}

// A set of files is committed as one: all written, replacing an old set whole.
TEST(OutputDirCommit, WritesTheSetAndReplacesAnOldOneWhole) {
  TempDir dir;
  const std::string out = dir.file("run");
  {
    const OutputDir held = prepare_output_dir(out, false);
    held.commit({{"report.json", "old report"}, {"model.json", "old model"}});
  }
  {
    const OutputDir held = prepare_output_dir(out, true);
    held.commit({{"report.json", "new report"}, {"model.json", "new model"}});
  }
  EXPECT_EQ(read_text_file(out + "/report.json"), "new report");
  EXPECT_EQ(read_text_file(out + "/model.json"), "new model");
  EXPECT_EQ(entries(out), 2u);  // no journal, no temporary, no lock left
}

// A full disk while the new set is written (injected: a file-size limit in a child process,
// so the second file's write fails with EFBIG) leaves the old set whole and no temporaries.
TEST(OutputDirCommit, AFailedWriteLeavesTheOldSetWhole) {
  TempDir dir;
  const std::string out = dir.file("run");
  {
    const OutputDir held = prepare_output_dir(out, false);
    held.commit({{"report.json", "old report"}, {"model.json", "old model"}});
  }
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    std::signal(SIGXFSZ, SIG_IGN);  // a write past the limit then fails with EFBIG
    const rlimit lim{4096, 4096};
    ::setrlimit(RLIMIT_FSIZE, &lim);
    try {
      const OutputDir held(out, true);
      held.commit({{"report.json", "new report"}, {"model.json", std::string(100000, 'm')}});
      ::_exit(0);
    } catch (const Error& e) {
      ::_exit(std::string(e.what()).find("model.json") != std::string::npos ? 7 : 8);
    }
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 7);  // refused, naming the file that could not be written
  EXPECT_EQ(read_text_file(out + "/report.json"), "old report");
  EXPECT_EQ(read_text_file(out + "/model.json"), "old model");
  EXPECT_EQ(entries(out), 2u);
}

// Killed between the renames: the journal names the temporaries still to rename, and the
// next command that takes the directory completes the new set before anything else.
TEST(OutputDirCommit, AKilledCommitIsRolledForward) {
  TempDir dir;
  const std::string out = dir.file("run");
  fs::create_directories(out);
  write_text_atomic(out + "/report.json", "new report");  // renamed before the kill
  write_text_atomic(out + "/model.json", "old model");
  write_text_atomic(out + "/.model.json.tmp.77.1.5", "new model");
  // A journal line outside the directory or not of the temp pattern is ignored.
  write_text_atomic(out + "/.csympnet.commit",
                    ".report.json.tmp.77.0.4\treport.json\n.model.json.tmp.77.1.5\tmodel.json\n"
                    "../escape\tx\n.x.tmp.1.2.3\t../../outside\n");
  {
    const OutputDir held = prepare_output_dir(out, true);
    EXPECT_EQ(read_text_file(out + "/report.json"), "new report");
    EXPECT_EQ(read_text_file(out + "/model.json"), "new model");
  }
  EXPECT_EQ(entries(out), 2u);
  EXPECT_FALSE(fs::exists(dir.file("outside")));
}

// A set may hold files one subdirectory down (reproduce's tables/): written, replaced and
// rolled forward like the rest; names that climb out or nest deeper are refused.
TEST(OutputDirCommit, SubdirectoriesAreOneSetWithTheRest) {
  TempDir dir;
  const std::string out = dir.file("rep");
  {
    const OutputDir held = prepare_output_dir(out, false);
    held.commit({{"summary.json", "old summary"}, {"tables/t.md", "old table"}});
    held.commit({{"summary.json", "new summary"}, {"tables/t.md", "new table"}});
    for (const std::string bad :
         {"../x", "tables/../../x", "a/b/c", "/abs", "tables/", "./x", "", "a\tb"}) {
      const std::string& name = bad;
      EXPECT_THROW(held.commit({{"ok.json", "x"}, {name, "y"}}), Error) << name;
    }
  }
  EXPECT_EQ(read_text_file(out + "/summary.json"), "new summary");
  EXPECT_EQ(read_text_file(out + "/tables/t.md"), "new table");
  EXPECT_FALSE(fs::exists(out + "/ok.json"));  // a refused set writes nothing
  EXPECT_EQ(entries(out + "/tables"), 1u);
  EXPECT_FALSE(fs::exists(dir.file("x")));

  // Killed between the renames of a set with a table: completed by the next command.
  write_text_atomic(out + "/tables/.t.md.tmp.77.1.5", "newest table");
  write_text_atomic(out + "/.csympnet.commit",
                    "tables/.t.md.tmp.77.1.5\ttables/t.md\n"
                    "tables/.t.md.tmp.77.1.5\tother/t.md\n");  // another directory: ignored
  { const OutputDir held = prepare_output_dir(out, true); }
  EXPECT_EQ(read_text_file(out + "/tables/t.md"), "newest table");
  EXPECT_FALSE(fs::exists(out + "/other"));
  EXPECT_FALSE(fs::exists(out + "/.csympnet.commit"));
}

TEST(PrepareOutputDir, RefusesAFile) {
  TempDir dir;
  const std::string file = dir.write("plain", "x");
  EXPECT_THROW(prepare_output_dir(file, false), Error);
  EXPECT_THROW(prepare_output_dir(file, true), Error);
}

}  // namespace
}  // namespace csympnet
