// `kernels`: which SIMD kernels run in this process and, for each that does not, why (the
// registry of src/kernels). The same summary follows the version line of --version. Neither
// touches a report: the kernels give the portable code's bits, so which ran is not recorded.
#include <iostream>
#include <string>

#include "commands.hpp"
#include "kernels/registry.hpp"

namespace csympnet::cli {

std::string kernels_summary() {
  // The arithmetic of the cores' products, where it is not the default (it changes results).
  const std::string arithmetic =
      kernels::arithmetic() == kernels::kDefaultArithmetic
          ? ""
          : std::string("\narithmetic: ") + kernels::to_string(kernels::arithmetic());
  std::string running;
  for (const kernels::KernelStatus& s : kernels::report()) {
    if (s.runs) running += (running.empty() ? "" : ", ") + s.name + " (" + s.isa + ")";
  }
  if (kernels::portable_forced_by_environment()) {
    return "kernels: portable code only (CSYMPNET_KERNELS=portable)" + arithmetic;
  }
  const std::string capped =
      kernels::avx2_capped_by_environment() ? ", capped at avx2 (CSYMPNET_KERNELS=avx2)" : "";
  return "kernels: " + (running.empty() ? std::string("portable code only") : running) + capped +
         " (`csympnet kernels` for each; CSYMPNET_KERNELS=portable forces the portable code)" +
         arithmetic;
}

void add_kernels(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "kernels",
      "List the SIMD kernels, whether each runs here and which form of each family is in use "
      "(CSYMPNET_KERNELS=portable forces the portable code, CSYMPNET_KERNELS=avx2 the forms of "
      "a CPU without AVX-512; all give the same bits)");
  cmd->callback([] {
    if (parse_only()) return;
    std::cout << kernels::report_text();
  });
}

}  // namespace csympnet::cli
