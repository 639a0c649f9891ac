// The registry of the kernels layer: every SIMD kernel family, the instruction set it needs,
// and the rule that decides whether it runs. A family's kernel is used only when
//   * this build compiled it (targets.hpp: kernels_built()),
//   * the CPU has its instruction set (targets.hpp: cpu(), the one probe),
//   * its self-check, run once per process, gave the portable code's results to the bit, and
//   * the portable path is not forced: CSYMPNET_KERNELS=portable in the environment (read once)
//     or a ForcePortable guard alive in this process, and
//   * for a family that needs AVX-512, the instruction set is not capped at AVX2:
//     CSYMPNET_KERNELS=avx2 in the environment or a CapAtAvx2 guard alive (so that a machine
//     with AVX-512 runs, and tests, the forms a machine without it would run).
// A family with forms for several instruction sets runs the widest that may run (AVX-512 before
// AVX2 or AVX).
// Everywhere else the portable code (Eigen's own expressions, SSE2 without FMA, or for the fma
// products their std::fma reference) runs; both give the same bits, so a forced or declined
// kernel costs time, never results.
//
// One choice does change results: the arithmetic of the cores' matrix products (Arithmetic
// below), set once per process.
//
// The first three are settled once per family and cached; use() reads three atomics after that.
#pragma once

#include <atomic>
#include <string>
#include <vector>

namespace csympnet::kernels {

enum class Family : int {
  kProductAvx512,      // the cores' matrix products in Eigen's SSE2 summation order (product.hpp)
  kProductAvx,         // the same with 256-bit registers, where AVX-512 is missing
  kSigmoid,            // σ over a contiguous array (sigmoid.hpp)
  kSigmoidAvx2,        // the same with AVX2, where AVX-512 is missing (and so on below)
  kScaledExp,          // exp(c h_j), CSympNet-ID's conformal factors (scaled_exp.hpp)
  kScaledExpAvx2,      // its AVX2 form
  kD1Sweeps,           // LA-SympNet's d = 1 forward and backward sweeps (d1_sweeps.hpp)
  kD1SweepsAvx2,       // its AVX2 form
  kConformalRows,      // CSympNet-ID's d = 1 row split, join and β terms (conformal_rows.hpp)
  kConformalRowsAvx2,  // its AVX2 form
  kColumnScaling,      // per-column scalings by h and bias outer products (column_scaling.hpp)
  kColumnScalingAvx2,  // its AVX2 form
  kAdamW,              // AdamW's elementwise update (adamw_update.hpp)
  kAdamWAvx2,          // its AVX2 form
  kFmaProductAvx512,   // the cores' matrix products in the fma arithmetic (fma_product.hpp)
  kFmaProductAvx2,     // the same with AVX2 + FMA, where AVX-512 is missing
  kCount
};

// Whether f's kernel needs AVX-512 (those that CSYMPNET_KERNELS=avx2 declines).
constexpr bool needs_avx512(Family f) {
  switch (f) {
    case Family::kProductAvx512:
    case Family::kSigmoid:
    case Family::kScaledExp:
    case Family::kD1Sweeps:
    case Family::kConformalRows:
    case Family::kColumnScaling:
    case Family::kAdamW:
    case Family::kFmaProductAvx512:
      return true;
    default:
      return false;
  }
}

namespace internal {
// > 0 while the portable path is forced (the environment counts once, each guard once).
extern std::atomic<int> g_forced;
// > 0 while the instruction set is capped at AVX2 (counted likewise).
extern std::atomic<int> g_capped;
// Per family: 0 not settled yet, 1 built, supported and checked, −1 not.
extern std::atomic<signed char> g_state[static_cast<int>(Family::kCount)];
bool settle(Family f);  // settles f (once) and answers use(f)
}  // namespace internal

// Whether f's kernel runs now. Cheap: the settled state and the forced count, both cached.
inline bool use(Family f) {
  const signed char s = internal::g_state[static_cast<int>(f)].load(std::memory_order_acquire);
  if (s == 0) return internal::settle(f);
  return s > 0 && internal::g_forced.load(std::memory_order_relaxed) == 0 &&
         (!needs_avx512(f) || internal::g_capped.load(std::memory_order_relaxed) == 0);
}

// Whether f's kernel is built, supported and checked, forced or not (for kernels made of other
// families' kernels, and for tests).
bool available(Family f);

// Whether the portable path is forced now (environment or guard).
bool portable_forced();
// Whether the instruction set is capped at AVX2 now (environment or guard).
bool avx2_capped();
// Throws Error unless CSYMPNET_KERNELS is unset, empty, 'portable' or 'avx2' (any other value
// was silently ignored before; the CLI checks it before any command starts).
void check_kernels_environment();

// Whether CSYMPNET_KERNELS=portable was in the environment when the process first asked.
bool portable_forced_by_environment();
// Whether CSYMPNET_KERNELS=avx2 was in the environment when the process first asked.
bool avx2_capped_by_environment();

// Forces the portable path for the guard's lifetime, in every thread (for tests and tools that
// compare both paths). Guards nest.
class ForcePortable {
 public:
  ForcePortable();
  ~ForcePortable();
  ForcePortable(const ForcePortable&) = delete;
  ForcePortable& operator=(const ForcePortable&) = delete;
};

// Declines every family that needs AVX-512 for the guard's lifetime, in every thread, so that
// the AVX2 forms run on a machine that has AVX-512 too (tests). Guards nest.
class CapAtAvx2 {
 public:
  CapAtAvx2();
  ~CapAtAvx2();
  CapAtAvx2(const CapAtAvx2&) = delete;
  CapAtAvx2& operator=(const CapAtAvx2&) = delete;
};

// A family whose portable reference lives above this layer (the d = 1 sweeps: LA-SympNet's own
// loops) has its self-check supplied from there, before its first use. Returns true.
bool supply_check(Family f, bool (*check)());

// The arithmetic of the SympNet cores' matrix products (docs/architecture.md, "Arithmetic of
// the products"):
//   kSse2: Eigen's SSE2 order, separate multiplies and adds (product.hpp): the portable build's
//          bits, which the sse2-order kernels reproduce;
//   kFma:  one chain of fused multiply-adds per entry (fma_product.hpp): the same bits on every
//          CPU and thread count, rounding-level different from kSse2.
enum class Arithmetic : int { kSse2, kFma };

// The default, where neither the environment nor set_arithmetic() chooses.
inline constexpr Arithmetic kDefaultArithmetic = Arithmetic::kSse2;

// "sse2" or "fma".
const char* to_string(Arithmetic a);
// "sse2" or "fma" to the Arithmetic; anything else throws Error naming `where` (the option or
// variable it came from) and the values expected.
Arithmetic parse_arithmetic(const std::string& value, const std::string& where);

// The process's arithmetic: the last set_arithmetic(), else CSYMPNET_ARITHMETIC=sse2|fma from
// the environment (read once; empty counts as unset), else kDefaultArithmetic. Throws Error for
// another value of the variable. Cheap after the first call (one atomic load).
Arithmetic arithmetic();
// Sets the process's arithmetic (the command line's --arithmetic, and tests), overriding the
// environment. Set it before any product runs: a model trained partly in each has no single one.
void set_arithmetic(Arithmetic a);
// Whether arithmetic() came from CSYMPNET_ARITHMETIC (and no set_arithmetic() since).
bool arithmetic_from_environment();

// Sets the arithmetic for the guard's lifetime and then restores the previous one (tests).
class UseArithmetic {
 public:
  explicit UseArithmetic(Arithmetic a);
  ~UseArithmetic();
  UseArithmetic(const UseArithmetic&) = delete;
  UseArithmetic& operator=(const UseArithmetic&) = delete;

 private:
  Arithmetic previous_;
  bool previous_from_environment_;
};

struct KernelStatus {
  std::string name;  // the family
  std::string isa;   // the instruction set its kernel needs
  bool runs = false;
  std::string why;  // "runs", or why the portable code runs instead
};

// Every family, in Family order, settled (self-checks run) if they were not yet.
std::vector<KernelStatus> report();

// Per family name, in Family order: the instruction set of the form that runs now, or
// "portable" (no form runs).
struct FormInUse {
  std::string name;
  std::string isa;
};
std::vector<FormInUse> forms_in_use();

// report() as text, one line per form: "name isa: runs" or "name isa: portable, why"; then one
// line "in use: name isa, name isa, …" (forms_in_use()); then one line
// "arithmetic: sse2|fma (default|CSYMPNET_ARITHMETIC|set)".
std::string report_text();

}  // namespace csympnet::kernels
