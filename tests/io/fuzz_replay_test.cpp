// Replays the fuzz corpora and every kept crash (fuzz/corpus/TARGET, fuzz/regressions/TARGET)
// through the same entry points the libFuzzer targets use, so the normal test suite guards
// against regressions without clang. An entry point answers bad input with csympnet::Error,
// which it swallows; any other exception fails here, and a broken contract aborts.
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <typeinfo>
#include <vector>

#include "../../fuzz/fuzz_cli_entry.hpp"

namespace csympnet {
namespace {

namespace fs = std::filesystem;

using Entry = int (*)(const std::uint8_t*, std::size_t);

std::vector<fs::path> inputs_of(const std::string& target) {
  std::vector<fs::path> files;
  for (const char* kind : {"corpus", "regressions"}) {
    const fs::path dir = fs::path(CSYMPNET_SOURCE_DIR) / "fuzz" / kind / target;
    if (!fs::is_directory(dir)) continue;
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file()) files.push_back(e.path());
  }
  return files;
}

std::size_t replay(const std::string& target, Entry entry) {
  const std::vector<fs::path> files = inputs_of(target);
  for (const fs::path& p : files) {
    std::ifstream in(p, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    try {
      entry(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
    } catch (const std::exception& e) {
      ADD_FAILURE() << p << ": escaped as " << typeid(e).name() << ": " << e.what();
    }
  }
  return files.size();
}

TEST(FuzzReplay, CsvPairsCorpusAndRegressions) {
  EXPECT_GE(replay("fuzz_csv_pairs", &fuzz::csv_pairs), 3u);
}

TEST(FuzzReplay, CsvTrajectoriesCorpusAndRegressions) {
  EXPECT_GE(replay("fuzz_csv_trajectories", &fuzz::csv_trajectories), 3u);
}

TEST(FuzzReplay, ModelFileCorpusAndRegressions) {
  EXPECT_GE(replay("fuzz_model_file", &fuzz::model_file), 3u);
}

// The entry points do reject bad input and accept good input (so the replay above is not
// vacuous): a pairs file round-trips, a garbage one is refused without escaping.
TEST(FuzzReplay, EntryPointsSeeTheParsers) {
  const std::string good = "h,q1,p1,next_q1,next_p1\n0.1,1,0,0.995,-0.0998\n";
  EXPECT_EQ(fuzz::csv_pairs(reinterpret_cast<const std::uint8_t*>(good.data()), good.size()), 0);
  EXPECT_EQ(parse_pairs_csv(good, "x.csv").size(), 1);
  EXPECT_THROW(parse_pairs_csv("h,q1\n", "x.csv"), Error);
  EXPECT_THROW(model_from_text("{\"format\": 1", "x.json"), Error);
}

TEST(FuzzReplay, CommandLineCorpusAndRegressions) {
  EXPECT_GE(replay("fuzz_cli_args", &fuzz::cli_args), 3u);
  fuzz::cli_args(nullptr, 0);  // no arguments at all
  cli::set_parse_only(false);
}

TEST(FuzzReplay, SuiteFileCorpusAndRegressions) {
  EXPECT_GE(replay("fuzz_suite_file", &fuzz::suite_file), 3u);
}

}  // namespace
}  // namespace csympnet
