// csympnet_bench: Google Benchmark's command line (--benchmark_filter, --benchmark_format,
// ...), plus
//   --peer-export=DIR [--peer-presets=s1,s2,...] [--peer-epochs=K]
// which writes the PyTorch peer's inputs (peer_export.hpp) and exits without benchmarking.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

#include "../src/kernels/product.hpp"   // which product kernels run, for the report
#include "../src/kernels/registry.hpp"  // and which form of every family
#include "bench_train.hpp"
#include "csympnet/core/error.hpp"
#include "peer_export.hpp"

namespace {

std::vector<std::string> split(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream in(text);
  for (std::string item; std::getline(in, item, ',');) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

// The value of --name=VALUE, if present.
const char* flag_value(const char* arg, const char* name) {
  const std::size_t len = std::strlen(name);
  if (std::strncmp(arg, name, len) == 0 && arg[len] == '=') return arg + len + 1;
  return nullptr;
}

}  // namespace

int main(int argc, char** argv) {
  std::string peer_dir;
  std::string peer_presets = "s1,s2,s3,s2-100";
  int peer_epochs = 5;
  std::vector<char*> rest{argv[0]};
  for (int i = 1; i < argc; ++i) {
    if (const char* v = flag_value(argv[i], "--peer-export")) {
      peer_dir = v;
    } else if (const char* v2 = flag_value(argv[i], "--peer-presets")) {
      peer_presets = v2;
    } else if (const char* v3 = flag_value(argv[i], "--peer-epochs")) {
      peer_epochs = std::atoi(v3);
    } else {
      rest.push_back(argv[i]);
    }
  }
  if (!peer_dir.empty()) {
    try {
      csympnet::bench::export_peer_inputs(peer_dir, split(peer_presets), peer_epochs);
    } catch (const csympnet::Error& e) {
      std::fprintf(stderr, "csympnet_bench: error: %s\n", e.what());
      return 1;
    }
    return 0;
  }
  int rest_argc = static_cast<int>(rest.size());
  benchmark::Initialize(&rest_argc, rest.data());
  if (benchmark::ReportUnrecognizedArguments(rest_argc, rest.data())) return 2;
  benchmark::AddCustomContext("exact_product", csympnet::kernels::product_kernel_isa());
  // Which form of each kernel family runs (CSYMPNET_KERNELS=avx2 makes an AVX-512 machine run
  // those of a machine without it).
  std::string forms;
  for (const auto& f : csympnet::kernels::forms_in_use()) {
    forms += (forms.empty() ? "" : ", ") + f.name + " " + f.isa;
  }
  benchmark::AddCustomContext("kernels", forms);
  csympnet::bench::register_benchmarks();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
