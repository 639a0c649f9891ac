#include "registry.hpp"

#include <cstdlib>
#include <cstring>
#include <mutex>

#include "csympnet/core/error.hpp"
#include "targets.hpp"

namespace csympnet::kernels {

// The self-checks, each in its family's kernel file: the kernel against the portable code on
// values of every kind it handles, bit for bit. Each returns false where it is not built.
bool product_avx512_self_check();
bool product_avx_self_check();
bool sigmoid_self_check();
bool sigmoid_avx2_self_check();
bool scaled_exp_self_check();
bool scaled_exp_avx2_self_check();
bool conformal_rows_self_check();
bool conformal_rows_avx2_self_check();
bool column_scaling_self_check();
bool column_scaling_avx2_self_check();
bool adamw_self_check();
bool adamw_avx2_self_check();
bool conformal_rows_built();  // built on any x86 GCC or clang build (no Eigen order involved)
bool fma_product_avx512_self_check();
bool fma_product_avx2_self_check();
bool fma_kernels_built();  // built on any x86 GCC build (the order is Eigen's nowhere)

namespace internal {
std::atomic<int> g_forced{0};
std::atomic<int> g_capped{0};
std::atomic<signed char> g_state[static_cast<int>(Family::kCount)] = {};
}  // namespace internal

namespace {

constexpr int kFamilies = static_cast<int>(Family::kCount);

struct Row {
  const char* name;
  const char* isa;
  bool (*built)();
  bool (*cpu_has)(const CpuFeatures&);
  int preferred;  // the family's wider form, chosen first where it runs (−1: none)
};

bool avx512f(const CpuFeatures& c) {
  return c.avx512f;
}
bool avx(const CpuFeatures& c) {
  return c.avx;
}
bool avx512f_vl(const CpuFeatures& c) {
  return c.avx512f && c.avx512vl;
}
bool avx2(const CpuFeatures& c) {
  return c.avx2;
}
bool avx2_fma(const CpuFeatures& c) {
  return c.avx2 && c.fma;
}

constexpr int of(Family f) {
  return static_cast<int>(f);
}

// In Family order.
const Row kRows[kFamilies] = {
    {"product", "avx512f", kernels_built, avx512f, -1},
    {"product", "avx", kernels_built, avx, of(Family::kProductAvx512)},
    {"sigmoid", "avx512f", kernels_built, avx512f, -1},
    {"sigmoid", "avx2", kernels_built, avx2, of(Family::kSigmoid)},
    {"scaled_exp", "avx512f", kernels_built, avx512f, -1},
    {"scaled_exp", "avx2", kernels_built, avx2, of(Family::kScaledExp)},
    {"d1_sweeps", "avx512f+avx512vl", kernels_built, avx512f_vl, -1},
    {"d1_sweeps", "avx2", kernels_built, avx2, of(Family::kD1Sweeps)},
    {"conformal_rows", "avx512f", conformal_rows_built, avx512f, -1},
    {"conformal_rows", "avx2", conformal_rows_built, avx2, of(Family::kConformalRows)},
    {"column_scaling", "avx512f", kernels_built, avx512f, -1},
    {"column_scaling", "avx2", kernels_built, avx2, of(Family::kColumnScaling)},
    {"adamw", "avx512f", kernels_built, avx512f, -1},
    {"adamw", "avx2", kernels_built, avx2, of(Family::kAdamW)},
    {"fma_product", "avx512f", fma_kernels_built, avx512f, -1},
    {"fma_product", "avx2+fma", fma_kernels_built, avx2_fma, of(Family::kFmaProductAvx512)},
};

std::atomic<bool (*)()> g_supplied[kFamilies] = {};

bool (*check_of(Family f))() {
  switch (f) {
    case Family::kProductAvx512:
      return product_avx512_self_check;
    case Family::kProductAvx:
      return product_avx_self_check;
    case Family::kSigmoid:
      return sigmoid_self_check;
    case Family::kSigmoidAvx2:
      return sigmoid_avx2_self_check;
    case Family::kScaledExp:
      return scaled_exp_self_check;
    case Family::kScaledExpAvx2:
      return scaled_exp_avx2_self_check;
    case Family::kConformalRows:
      return conformal_rows_self_check;
    case Family::kConformalRowsAvx2:
      return conformal_rows_avx2_self_check;
    case Family::kColumnScaling:
      return column_scaling_self_check;
    case Family::kColumnScalingAvx2:
      return column_scaling_avx2_self_check;
    case Family::kAdamW:
      return adamw_self_check;
    case Family::kAdamWAvx2:
      return adamw_avx2_self_check;
    case Family::kFmaProductAvx512:
      return fma_product_avx512_self_check;
    case Family::kFmaProductAvx2:
      return fma_product_avx2_self_check;
    default:
      return g_supplied[static_cast<int>(f)].load(std::memory_order_acquire);
  }
}

// Why a family does not run, once settled ("" when it does, forced or not).
const char* g_why[kFamilies] = {};
std::once_flag g_once[kFamilies];
std::once_flag g_env_once;
bool g_env_forced = false;
bool g_env_capped = false;

void read_environment() {
  std::call_once(g_env_once, [] {
    const char* v = std::getenv("CSYMPNET_KERNELS");
    g_env_forced = v != nullptr && std::strcmp(v, "portable") == 0;
    g_env_capped = v != nullptr && std::strcmp(v, "avx2") == 0;
    if (g_env_forced) internal::g_forced.fetch_add(1, std::memory_order_relaxed);
    if (g_env_capped) internal::g_capped.fetch_add(1, std::memory_order_relaxed);
  });
}

void settle_once(Family f) {
  const int i = static_cast<int>(f);
  std::call_once(g_once[i], [f, i] {
    const Row& r = kRows[i];
    const char* why = "";
    if (!r.built()) {
      why = r.built == fma_kernels_built ? "not built (not GCC on x86)"
                                         : "not built (this build's Eigen is not the SSE2 path "
                                           "without FMA, or not GCC on x86)";
    } else if (!r.cpu_has(cpu())) {
      why = "the CPU lacks it";
    } else if (check_of(f) == nullptr) {
      why = "no self-check supplied (its model is not linked)";
    } else if (!check_of(f)()) {
      why = "its self-check differed from the portable code";
    }
    g_why[i] = why;
    internal::g_state[i].store(why[0] == '\0' ? 1 : -1, std::memory_order_release);
  });
}

}  // namespace

namespace internal {
bool settle(Family f) {
  read_environment();
  settle_once(f);
  return use(f);
}
}  // namespace internal

bool available(Family f) {
  read_environment();
  settle_once(f);
  return internal::g_state[static_cast<int>(f)].load(std::memory_order_acquire) > 0;
}

bool portable_forced() {
  read_environment();
  return internal::g_forced.load(std::memory_order_relaxed) > 0;
}

bool portable_forced_by_environment() {
  read_environment();
  return g_env_forced;
}

bool avx2_capped() {
  read_environment();
  return internal::g_capped.load(std::memory_order_relaxed) > 0;
}

bool avx2_capped_by_environment() {
  read_environment();
  return g_env_capped;
}

CapAtAvx2::CapAtAvx2() {
  read_environment();
  internal::g_capped.fetch_add(1, std::memory_order_relaxed);
}

CapAtAvx2::~CapAtAvx2() {
  internal::g_capped.fetch_sub(1, std::memory_order_relaxed);
}

ForcePortable::ForcePortable() {
  read_environment();
  internal::g_forced.fetch_add(1, std::memory_order_relaxed);
}

ForcePortable::~ForcePortable() {
  internal::g_forced.fetch_sub(1, std::memory_order_relaxed);
}

bool supply_check(Family f, bool (*check)()) {
  g_supplied[static_cast<int>(f)].store(check, std::memory_order_release);
  return true;
}

namespace {

// −1 until the first arithmetic() or set_arithmetic(); then an Arithmetic.
std::atomic<int> g_arithmetic{-1};
std::atomic<bool> g_arithmetic_env{false};
std::mutex g_arithmetic_mutex;

bool is_product(Family f) {
  return f == Family::kProductAvx512 || f == Family::kProductAvx;
}
bool is_fma_product(Family f) {
  return f == Family::kFmaProductAvx512 || f == Family::kFmaProductAvx2;
}

}  // namespace

void check_kernels_environment() {
  const char* v = std::getenv("CSYMPNET_KERNELS");
  if (v == nullptr || v[0] == '\0' || std::strcmp(v, "portable") == 0 ||
      std::strcmp(v, "avx2") == 0) {
    return;
  }
  throw Error("CSYMPNET_KERNELS = '" + printable(std::string(v).substr(0, 100)) +
              "': unknown value; expected 'portable' (the portable code only), 'avx2' (no "
              "kernel that needs AVX-512: what a CPU without it runs) or the variable unset "
              "(the fastest kernels this CPU runs)");
}

const char* to_string(Arithmetic a) {
  return a == Arithmetic::kFma ? "fma" : "sse2";
}

Arithmetic parse_arithmetic(const std::string& value, const std::string& where) {
  if (value == "sse2") return Arithmetic::kSse2;
  if (value == "fma") return Arithmetic::kFma;
  const bool sse2_default = kDefaultArithmetic == Arithmetic::kSse2;
  throw Error(
      where + " = '" + value + "': unknown arithmetic; expected 'sse2' (Eigen's SSE2 order" +
      (sse2_default ? ", the default" : "") + ") or 'fma' (one fused multiply-add chain per entry" +
      (sse2_default ? "" : ", the default") + ")");
}

Arithmetic arithmetic() {
  const int a = g_arithmetic.load(std::memory_order_acquire);
  if (a >= 0) return static_cast<Arithmetic>(a);
  const std::lock_guard<std::mutex> lock(g_arithmetic_mutex);
  if (g_arithmetic.load(std::memory_order_acquire) < 0) {
    const char* v = std::getenv("CSYMPNET_ARITHMETIC");
    Arithmetic chosen = kDefaultArithmetic;
    if (v != nullptr && v[0] != '\0') {
      chosen = parse_arithmetic(v, "CSYMPNET_ARITHMETIC");  // throws, leaving it unsettled
      g_arithmetic_env.store(true, std::memory_order_relaxed);
    }
    g_arithmetic.store(static_cast<int>(chosen), std::memory_order_release);
  }
  return static_cast<Arithmetic>(g_arithmetic.load(std::memory_order_acquire));
}

void set_arithmetic(Arithmetic a) {
  const std::lock_guard<std::mutex> lock(g_arithmetic_mutex);
  g_arithmetic_env.store(false, std::memory_order_relaxed);
  g_arithmetic.store(static_cast<int>(a), std::memory_order_release);
}

bool arithmetic_from_environment() {
  (void)arithmetic();
  return g_arithmetic_env.load(std::memory_order_relaxed);
}

UseArithmetic::UseArithmetic(Arithmetic a)
    : previous_(arithmetic()), previous_from_environment_(arithmetic_from_environment()) {
  set_arithmetic(a);
}

UseArithmetic::~UseArithmetic() {
  set_arithmetic(previous_);
  g_arithmetic_env.store(previous_from_environment_, std::memory_order_relaxed);
}

std::vector<KernelStatus> report() {
  const Arithmetic mode = arithmetic();
  std::vector<KernelStatus> out;
  for (int i = 0; i < kFamilies; ++i) {
    const auto f = static_cast<Family>(i);
    KernelStatus s;
    s.name = kRows[i].name;
    s.isa = kRows[i].isa;
    const bool ok = available(f);
    const bool capped = needs_avx512(f) && avx2_capped();
    s.runs = ok && !portable_forced() && !capped;
    const int preferred = kRows[i].preferred;
    if (s.runs && is_product(f) && mode != Arithmetic::kSse2) {
      s.runs = false;
      s.why = std::string("not chosen: the arithmetic is ") + to_string(mode);
    } else if (s.runs && is_fma_product(f) && mode != Arithmetic::kFma) {
      s.runs = false;
      s.why = std::string("not chosen: the arithmetic is ") + to_string(mode) +
              " (CSYMPNET_ARITHMETIC=fma selects it)";
    } else if (s.runs && preferred >= 0 && use(static_cast<Family>(preferred))) {
      s.runs = false;  // the family takes its wider form first
      s.why =
          std::string("not chosen: the ") + kRows[preferred].isa + " " + s.name + " kernel runs";
    } else if (s.runs) {
      s.why = "runs";
    } else if (!ok) {
      s.why = g_why[i];
    } else if (portable_forced()) {
      s.why = portable_forced_by_environment() ? "forced portable (CSYMPNET_KERNELS=portable)"
                                               : "forced portable (ForcePortable)";
    } else {
      s.why = avx2_capped_by_environment() ? "capped at avx2 (CSYMPNET_KERNELS=avx2)"
                                           : "capped at avx2 (CapAtAvx2)";
    }
    out.push_back(std::move(s));
  }
  return out;
}

std::vector<FormInUse> forms_in_use() {
  std::vector<FormInUse> out;
  for (const KernelStatus& s : report()) {
    if (out.empty() || out.back().name != s.name) out.push_back({s.name, "portable"});
    if (s.runs) out.back().isa = s.isa;
  }
  return out;
}

std::string report_text() {
  std::string text;
  for (const KernelStatus& s : report()) {
    text += s.name + " " + s.isa + ": " + (s.runs ? std::string("runs") : "portable, " + s.why);
    text += '\n';
  }
  std::string in_use;
  for (const FormInUse& f : forms_in_use()) {
    in_use += (in_use.empty() ? "" : ", ") + f.name + " " + f.isa;
  }
  text += "in use: " + in_use + '\n';
  const Arithmetic mode = arithmetic();
  text += std::string("arithmetic: ") + to_string(mode) +
          (arithmetic_from_environment() ? " (CSYMPNET_ARITHMETIC)"
           : mode == kDefaultArithmetic  ? " (default)"
                                         : " (set)") +
          '\n';
  return text;
}

}  // namespace csympnet::kernels
