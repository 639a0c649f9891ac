#include "csympnet/io/files.hpp"

#include <gtest/gtest.h>

#include <filesystem>

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

TEST(PrepareOutputDir, CreatesMissingAndAcceptsEmpty) {
  TempDir dir;
  const std::string nested = dir.file("a/b/c");
  prepare_output_dir(nested, false);
  EXPECT_TRUE(fs::is_directory(nested));
  EXPECT_NO_THROW(prepare_output_dir(nested, false));  // exists but empty
}

TEST(PrepareOutputDir, RefusesNonEmptyWithoutForce) {
  TempDir dir;
  const std::string out = dir.file("run");
  prepare_output_dir(out, false);
  write_text_atomic(out + "/result.json", "{}");
  try {
    prepare_output_dir(out, false);
    FAIL();
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(out), std::string::npos) << msg;
    EXPECT_NE(msg.find("overwrite"), std::string::npos) << msg;
    EXPECT_NE(msg.find("--force"), std::string::npos) << msg;
  }
  EXPECT_NO_THROW(prepare_output_dir(out, true));
  EXPECT_EQ(read_text_file(out + "/result.json"), "{}");  // force does not delete anything
}

TEST(PrepareOutputDir, RefusesAFile) {
  TempDir dir;
  const std::string file = dir.write("plain", "x");
  EXPECT_THROW(prepare_output_dir(file, false), Error);
  EXPECT_THROW(prepare_output_dir(file, true), Error);
}

}  // namespace
}  // namespace csympnet
