// libFuzzer target: see fuzz_cli_entry.hpp for what counts as a finding.
#include "fuzz_cli_entry.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return csympnet::fuzz::cli_args(data, size);
}
