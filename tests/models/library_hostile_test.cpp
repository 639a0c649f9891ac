// The Hamiltonian-library map against hostile input (docs/hardening.md):
//   - term names of any length, and indices past any integer, are refused by name (a name of
//     50,000 digits overflowed the stack in std::regex; 20 digits escaped as std::stol's
//     out_of_range);
//   - 100,000 terms build in linear time (a search of the terms before each took 13-31 s for
//     141,000), and sin and cos of one argument still share their wavenumber;
//   - a step of many substeps polls the stop request (Ctrl-C was ignored for 4,000,000), and one
//     of the identification's sizes never does;
//   - a model file whose inverse mass is not positive definite is refused at load, by key.
#include <chrono>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "csympnet/core/error.hpp"
#include "csympnet/core/rng.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/models/hamiltonian_library.hpp"
#include "csympnet/models/model_file.hpp"
#include "csympnet/models/potential_library.hpp"

namespace csympnet {
namespace {

std::string term_refusal(const std::string& name, Index d) {
  try {
    parse_term(name, d, "spec.terms");
  } catch (const Error& e) {
    return e.what();
  }
  return "accepted";
}

TEST(LibraryHostile, LongNamesAndHugeIndicesAreRefusedByName) {
  const std::string digits(50000, '1');
  for (const std::string& name :
       {"q" + digits, "q1^" + digits, "sin(q" + digits + ")", "(q1-q" + digits + ")^2",
        "exp(-q" + digits + ")", "cos(q1-q2" + digits + ")", "q1" + std::string(50000, ' ')}) {
    const std::string m = term_refusal(name, 3);
    EXPECT_NE(m.find("spec.terms: term '" + name.substr(0, 40) + "\u2026'"), std::string::npos)
        << m.substr(0, 200);
    EXPECT_LT(m.size(), 600u) << "the message quotes the whole name";
  }
  EXPECT_NE(term_refusal("q" + digits, 3).find("out of range"), std::string::npos);
  EXPECT_NE(term_refusal("q1^" + digits, 3).find("not a library term"), std::string::npos);
  for (const char* name : {"q99999999999999999999", "q18446744073709551617",
                           "sin(q1-q99999999999999999999)", "(q99999999999999999999-q1)^2"}) {
    const std::string m = term_refusal(name, 2);
    EXPECT_NE(m.find("out of range"), std::string::npos) << name << ": " << m;
    EXPECT_NE(m.find("I, J in 1..2"), std::string::npos) << m;
  }
  EXPECT_NE(term_refusal("q0", 2).find("coordinate 0 out of range"), std::string::npos);
  EXPECT_NE(term_refusal("q3", 2).find("coordinate 3 out of range"), std::string::npos);
  // The grammar is the one the regular expressions had: near misses stay refused, leading
  // zeros are written back in the canonical form, and every canonical name still parses.
  for (const char* name : {"", "q", "q1^", "q1^22", "(q1-q2)", "(q1-q2)^", "sin(q1", "sin(q1-)",
                           "exp(--q1)", "sinq1", "q1 ", " q1", "q-1", "(q1+q2)^2", "sin(q1)x"})
    EXPECT_NE(term_refusal(name, 2).find("not a library term"), std::string::npos) << name;
  EXPECT_NE(term_refusal("q01", 2).find("write it as 'q1'"), std::string::npos);
  EXPECT_NE(term_refusal("exp(-q1-q2)", 2).find("minus sign"), std::string::npos);
  for (const LibraryTerm& t : full_library(12)) EXPECT_EQ(parse_term(term_name(t), 12, "t"), t);
}

TEST(LibraryHostile, ManyTermsBuildInLinearTime) {
  // 100,000 distinct terms: powers of 25,000 coordinates. A search of the terms before each
  // made this 5e9 comparisons.
  const Index d = 25000;
  std::vector<LibraryTerm> terms;
  for (Index i = 0; i < d; ++i)
    for (int n = 1; n <= 4; ++n) terms.push_back({i, -1, TermShape::kPower, n, 1.0});
  const auto t0 = std::chrono::steady_clock::now();
  const HamiltonianLibraryMap map(d, terms, 2, 1, false, 0.1);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_EQ(map.terms().size(), 100000u);
  EXPECT_LT(seconds, 2.0);
  terms.push_back(terms[54321]);
  try {
    HamiltonianLibraryMap twice(d, terms, 2, 1, false, 0.1);
    FAIL() << "a repeated term was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("'q13581^2' appears twice"), std::string::npos)
        << e.what();
  }
  // Wavenumbers: sin and cos of one argument share one, in term order; exp has its own.
  const HamiltonianLibraryMap waves(
      2,
      {parse_term("sin(q1)", 2, "t"), parse_term("exp(q1)", 2, "t"), parse_term("q2^2", 2, "t"),
       parse_term("cos(q1-q2)", 2, "t"), parse_term("cos(q1)", 2, "t"),
       parse_term("sin(q1-q2)", 2, "t")},
      2, 1, true, 0.1);
  const Index first = waves.mass_size() + 6;
  EXPECT_EQ(waves.wavenumber_index(0), first);
  EXPECT_EQ(waves.wavenumber_index(1), first + 1);
  EXPECT_EQ(waves.wavenumber_index(2), -1);
  EXPECT_EQ(waves.wavenumber_index(3), first + 2);
  EXPECT_EQ(waves.wavenumber_index(4), first);
  EXPECT_EQ(waves.wavenumber_index(5), first + 2);
  EXPECT_EQ(waves.n_params(), first + 4);
}

int g_polls = 0;
bool g_stop = false;
bool counting_poll() {
  ++g_polls;
  return g_stop;
}

struct PollGuard {
  PollGuard() {
    g_polls = 0;
    g_stop = false;
    set_stop_poll(&counting_poll);
  }
  ~PollGuard() { set_stop_poll(nullptr); }
};

TEST(LibraryHostile, AStepOfManySubstepsStopsOnRequest) {
  const PollGuard guard;
  const HamiltonianLibraryMap huge(1, {parse_term("q1^2", 1, "t")}, 2, 4000000, true, 0.1);
  Vector theta(huge.n_params());
  Rng rng(1, "unused");
  huge.init_params(rng, theta);
  const Matrix z = Matrix::Constant(2, 1, 0.5);
  const Vector h = Vector::Constant(1, 0.1);
  g_stop = true;
  EXPECT_THROW(huge.apply(theta, z, h), StopRequested);
  EXPECT_THROW(huge.jacobian(theta, z.col(0), 0.1), StopRequested);
  EXPECT_EQ(g_polls, 2) << "the first poll is 4096 stages in";
  // The identification's largest map (256 substeps of order 6: 2,304 stages) never polls, so
  // its training keeps stopping at its own checkpoints.
  g_polls = 0;
  const HamiltonianLibraryMap fit_sized(1, {parse_term("q1^2", 1, "t")}, 6, 256, true, 0.1);
  Vector theta2(fit_sized.n_params());
  fit_sized.init_params(rng, theta2);
  ForwardCache cache;
  const Matrix out = fit_sized.forward(theta2, z, h, &cache);
  Vector grad = Vector::Zero(fit_sized.n_params());
  fit_sized.backward(theta2, cache, out, grad, nullptr);
  fit_sized.jacobian(theta2, z.col(0), 0.1);
  EXPECT_EQ(g_polls, 0);
  EXPECT_TRUE(out.allFinite());
}

// A model file of a library map with θ's inverse-mass entries replaced.
std::string library_file(const std::string& mass, const std::vector<double>& w) {
  const Model model =
      make_model({{"type", "csympnet"},
                  {"d", 2},
                  {"core", {{"type", "library"}, {"terms", {"q1^2", "q2^2"}}, {"mass", mass}}}});
  Vector theta(model.n_params());
  Rng rng(1, "unused");
  model.init_params(rng, theta);
  for (std::size_t k = 0; k < w.size(); ++k) theta(static_cast<Index>(k)) = w[k];
  return model_file_text(model, theta, nlohmann::json::object());
}

std::string load_refusal(const std::string& text) {
  try {
    model_from_text(text, "m.json");
  } catch (const Error& e) {
    return e.what();
  }
  return "accepted";
}

TEST(LibraryHostile, AnInverseMassThatIsNotPositiveDefiniteIsRefusedAtLoad) {
  EXPECT_EQ(load_refusal(library_file("diagonal", {1.0, 0.5})), "accepted");
  EXPECT_EQ(load_refusal(library_file("full", {1.0, 0.9, 1.0})), "accepted");
  std::string m = load_refusal(library_file("diagonal", {1.0, 0.0}));
  EXPECT_NE(m.find("m.json: params[1] = 0 is W[2,2] (the inverse mass W = M^-1 of core 'mass': "
                   "\"diagonal\"); expected a positive inverse mass"),
            std::string::npos)
      << m;
  m = load_refusal(library_file("diagonal", {-2.5, 1.0}));
  EXPECT_NE(m.find("params[0] = -2.5 is W[1,1]"), std::string::npos) << m;
  m = load_refusal(library_file("full", {1.0, 0.0, -1e-300}));
  EXPECT_NE(m.find("params[2] = -1"), std::string::npos) << m;
  EXPECT_NE(m.find("e-300 is W[2,2]"), std::string::npos) << m;
  // Positive diagonal, yet indefinite: W = [[1, 2], [2, 1]].
  m = load_refusal(library_file("full", {1.0, 2.0, 1.0}));
  EXPECT_NE(m.find("m.json: params[0..2] (the inverse mass W = M^-1 of core 'mass': \"full\") "
                   "are not positive definite"),
            std::string::npos)
      << m;
}

}  // namespace
}  // namespace csympnet
