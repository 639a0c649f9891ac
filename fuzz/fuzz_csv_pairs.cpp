// libFuzzer target: see fuzz_entry.hpp for what counts as a finding.
#include "fuzz_entry.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return csympnet::fuzz::csv_pairs(data, size);
}
