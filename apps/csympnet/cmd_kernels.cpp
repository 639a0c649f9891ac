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
  return "kernels: " + (running.empty() ? std::string("portable code only") : running) +
         " (`csympnet kernels` for each; CSYMPNET_KERNELS=portable forces the portable code)" +
         arithmetic;
}

void add_kernels(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "kernels",
      "List the SIMD kernels and whether each runs here (CSYMPNET_KERNELS=portable forces the "
      "portable code; both give the same bits)");
  cmd->callback([] {
    if (parse_only()) return;
    std::cout << kernels::report_text();
  });
}

}  // namespace csympnet::cli
