// Malformed CSV input: every case must throw Error naming the file, the line, and what was
// expected. The cases are data, so adding one is one line.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <functional>

#include "csympnet/core/error.hpp"
#include "csympnet/data/csv.hpp"
#include "temp_dir.hpp"

namespace csympnet {
namespace {

using testing::TempDir;

enum class Reader { kPairs, kTrajectories, kAny, kDetect };

struct BadCase {
  const char* name;
  Reader reader;
  std::string content;
  int line;          // expected "file:line:" in the message; 0 when no line applies
  const char* says;  // a fragment naming what is wrong
};

const std::string kPairsHeader = "h,q1,p1,next_q1,next_p1\n";
const std::string kTrajHeader = "traj,t,q1,p1\n";

std::vector<BadCase> bad_cases() {
  const std::string ph = kPairsHeader, th = kTrajHeader;
  return {
      {"empty", Reader::kAny, "", 1, "file is empty"},
      {"only_blank_lines", Reader::kPairs, "  \n\r\n\n", 1, "file is empty"},
      {"header_only_pairs", Reader::kPairs, ph, 1, "no data rows"},
      {"header_only_traj", Reader::kTrajectories, th, 1, "no data rows"},
      {"too_few_fields", Reader::kPairs, ph + "1,2,3,4,5\n1,2,3,4\n", 3, "found 4 fields"},
      {"too_many_fields", Reader::kPairs, ph + "1,2,3,4,5,6\n", 2, "found 6 fields"},
      {"traj_wrong_count", Reader::kTrajectories, th + "0,1,2\n", 2, "found 3 fields"},
      {"text_abc", Reader::kPairs, ph + "1,abc,3,4,5\n", 2, "column 'q1'"},
      {"trailing_junk", Reader::kPairs, ph + "1,2,1.0x,4,5\n", 2, "'1.0x', which is not a number"},
      {"empty_field", Reader::kPairs, ph + "1,2,3,,5\n", 2, "column 'next_q1'"},
      {"double_minus", Reader::kPairs, ph + "1,2,3,4,--1\n", 2, "'--1', which is not a number"},
      {"plus_minus", Reader::kPairs, ph + "1,+-2,3,4,5\n", 2, "not a number"},
      {"hex", Reader::kPairs, ph + "1,0x10,3,4,5\n", 2, "not a number"},
      {"nan", Reader::kPairs, ph + "1,nan,3,4,5\n", 2, "NaN and infinities"},
      {"inf", Reader::kPairs, ph + "1,2,inf,4,5\n", 2, "NaN and infinities"},
      {"minus_inf", Reader::kTrajectories, th + "0,1,-inf,2\n", 2, "NaN and infinities"},
      {"overflow", Reader::kPairs, ph + "1,2,3,1e999,5\n", 2, "outside the range of double"},
      {"underflow", Reader::kPairs, ph + "1,2,3,1e-999,5\n", 2, "outside the range of double"},
      {"h_zero", Reader::kPairs, ph + "0.1,1,2,3,4\n0,1,2,3,4\n", 3, "h > 0"},
      {"h_negative", Reader::kAny, ph + "-0.1,1,2,3,4\n", 2, "h > 0"},
      {"unknown_header", Reader::kDetect, "x,y\n1,2\n", 1, "unrecognised header"},
      {"header_wrong_order", Reader::kPairs, "h,p1,q1,next_q1,next_p1\n1,2,3,4,5\n", 1,
       "header column 2 is 'p1'; expected 'q1'"},
      {"header_misnamed", Reader::kPairs, "h,q1,p1,nxt_q1,next_p1\n1,2,3,4,5\n", 1, "0 next_q"},
      {"header_q_ne_p", Reader::kPairs, "h,q1,next_q1\n1,2,3\n", 1, "has positions but no momenta"},
      {"header_odd_traj", Reader::kTrajectories, "t,q1,q2,p1\n1,2,3,4\n", 1, "2 q and 1 p"},
      {"header_traj_no_t", Reader::kTrajectories, "traj,x,q1,p1\n0,1,2,3\n", 1, "expected 't'"},
      {"header_case", Reader::kPairs, "h,Q1,p1,next_q1,next_p1\n1,2,3,4,5\n", 1, "0 q"},
      {"blank_line_inside", Reader::kPairs, ph + "1,2,3,4,5\n\n1,2,3,4,5\n", 3, "blank line"},
      {"pairs_as_traj", Reader::kTrajectories, ph + "1,2,3,4,5\n", 1, "trajectories header"},
      {"traj_as_pairs", Reader::kPairs, th + "0,1,2,3\n", 1, "pairs header"},
      {"t_repeated", Reader::kTrajectories, th + "0,0,1,2\n0,0.5,1,2\n0,0.5,1,2\n", 4,
       "strictly increase"},
      {"t_decreasing", Reader::kAny, "t,q1,p1\n0,1,2\n1,1,2\n0.5,1,2\n", 4, "on line 3"},
      {"traj_id_float", Reader::kTrajectories, th + "1.5,0,1,2\n", 2, "integer trajectory id"},
      {"traj_id_text", Reader::kTrajectories, th + "0,0,1,2\nabc,1,1,2\n", 3,
       "integer trajectory id"},
      {"traj_id_empty", Reader::kAny, th + ",0,1,2\n", 2, "integer trajectory id"},
      {"traj_id_reappears", Reader::kTrajectories, th + "0,0,1,2\n0,1,1,2\n1,0,1,2\n0,2,1,2\n", 5,
       "mismatched trajectory ids: id 0 reappears after its rows on lines 2-3"},
      {"no_pairs", Reader::kAny, th + "0,0,1,2\n1,0,1,2\n", 0, "no pairs"},
      {"nul_byte", Reader::kPairs, ph + "1,2,3,4,5\n1,2" + std::string(1, '\0') + ",3,4,5\n", 3,
       "NUL byte"},
      {"invalid_utf8", Reader::kPairs, ph + "1,\xff\xfe,3,4,5\n", 2, "byte 0xFF"},
      {"utf8_in_header", Reader::kDetect, "h,q\xc3\xa9\n", 1, "not printable ASCII"},
      {"stray_cr", Reader::kPairs, ph + "1,2,3,4,5\r1,2,3,4,5\n", 2, "carriage return"},
      {"control_char", Reader::kPairs, ph + "1,2,3\x01,4,5\n", 2, "byte 0x01"},
  };
}

void run(Reader r, const std::string& path) {
  switch (r) {
    case Reader::kPairs:
      read_pairs_csv(path);
      break;
    case Reader::kTrajectories:
      read_trajectories_csv(path);
      break;
    case Reader::kAny:
      read_any_as_pairs(path);
      break;
    case Reader::kDetect:
      detect_csv_kind(path);
      break;
  }
}

// Returns the Error message, or fails the test if something else (or nothing) happened.
std::string error_of(Reader r, const std::string& path) {
  try {
    run(r, path);
  } catch (const Error& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "not a csympnet::Error: " << e.what();
    return {};
  }
  ADD_FAILURE() << "no Error for " << path;
  return {};
}

TEST(CsvMalformed, EveryCaseNamesFileLineAndExpectation) {
  TempDir dir;
  for (const BadCase& c : bad_cases()) {
    SCOPED_TRACE(c.name);
    const std::string path = dir.write(std::string(c.name) + ".csv", c.content);
    const std::string msg = error_of(c.reader, path);
    const std::string where = c.line > 0 ? path + ":" + std::to_string(c.line) + ":" : path;
    EXPECT_NE(msg.find(where), std::string::npos) << "want '" << where << "' in: " << msg;
    EXPECT_NE(msg.find("expected"), std::string::npos) << msg;
    EXPECT_NE(msg.find(c.says), std::string::npos) << "want '" << c.says << "' in: " << msg;
  }
}

// Prints every message once, so a reviewer can read what users will see.
TEST(CsvMalformed, ListMessages) {
  TempDir dir;
  for (const BadCase& c : bad_cases())
    std::cout << c.name << " | "
              << error_of(c.reader, dir.write(std::string(c.name) + ".csv", c.content)) << "\n";
}

TEST(CsvMalformed, MissingFileAndDirectory) {
  TempDir dir;
  const std::string missing = dir.file("nope.csv");
  EXPECT_NE(error_of(Reader::kPairs, missing).find(missing + "': no such file"), std::string::npos);
  EXPECT_NE(error_of(Reader::kDetect, dir.path().string()).find("is a directory"),
            std::string::npos);
}

TEST(CsvMalformed, UnreadableFile) {
  if (::geteuid() == 0) GTEST_SKIP() << "root can read a file without permissions";
  TempDir dir;
  const std::string locked = dir.write("locked.csv", kPairsHeader + "1,2,3,4,5\n");
  std::filesystem::permissions(locked, std::filesystem::perms::none);
  const std::string msg = error_of(Reader::kPairs, locked);
  EXPECT_NE(msg.find(locked), std::string::npos) << msg;
  EXPECT_NE(msg.find("expected a readable file"), std::string::npos) << msg;
}

TEST(CsvMalformed, HugeLineFailsFastWithShortMessage) {
  TempDir dir;
  const std::string path =
      dir.write("huge.csv", kPairsHeader + "1,2,3,4," + std::string(20'000'000, '7') + "x\n");
  const auto start = std::chrono::steady_clock::now();
  const std::string msg = error_of(Reader::kPairs, path);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
  EXPECT_NE(msg.find(path + ":2: column 'next_p1'"), std::string::npos) << msg;
  EXPECT_LT(msg.size(), 400u);
}

TEST(CsvMalformed, SinglePointTrajectoriesAreReadableButGiveNoPairs) {
  TempDir dir;
  const std::string path = dir.write("single.csv", kTrajHeader + "0,0,1,2\n");
  EXPECT_EQ(read_trajectories_csv(path).size(), 1u);
  EXPECT_THROW(read_any_as_pairs(path), Error);
}

}  // namespace
}  // namespace csympnet
