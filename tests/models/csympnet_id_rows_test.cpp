// CSympNetId::forward/backward split and join the state rows by hand, reuse the cache's storage,
// compute a = exp(−γ̂h/2) with the AVX-512 exp where it runs, and, for d = 1, form the column
// sums of the β gradient as single products (src/models/csympnet_id.cpp). None of that may
// change a bit: this file keeps the previous implementation, written with Eigen expressions
// (as in commit 27933b9), and compares the output, everything recorded in the cache, dL/dθ and
// dL/dZin bit for bit, on LA and G cores, d = 1 and d > 1, batch sizes around the kernels'
// blocks, β of either sign and 0, and steps large enough to send the exp to Eigen's routine.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <random>

#include "../src/models/csympnet_id.hpp"
#include "../src/models/g_sympnet.hpp"
#include "../src/models/la_sympnet.hpp"
#include "csympnet/core/error.hpp"
#include "support/flow_records.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

// What the reference forward records: as CSympNetId::Context, without the working buffers.
struct Recorded {
  Vector h, a;
  Matrix p_in, p_core;
  ForwardCache core;
};

// The same list as csympnet_records() (support/flow_records.hpp) gives for the model's cache.
std::vector<Matrix> records_of(const CSympNetId& m, const Recorded& rec) {
  std::vector<Matrix> out = {rec.h.transpose(), rec.a.transpose(), rec.p_in, rec.p_core};
  for (const Matrix* r : flow_records(m.core(), rec.core)) out.push_back(*r);
  return out;
}

// The previous CSympNetId::forward, verbatim but for the core accessor and where it records.
Matrix reference_forward(const CSympNetId& m, ConstParams theta, const Matrix& Z, const Vector& h,
                         Recorded* cache) {
  const SymplecticCore& core = m.core();
  const Index d = core.d();
  const Index nc = core.n_params();
  const double gamma = std::abs(theta(nc));
  const Vector a = (-0.5 * gamma * h.array()).exp().matrix();
  Matrix q = Z.topRows(d);
  Matrix p = Z.bottomRows(d);
  p.array().rowwise() *= a.transpose().array();
  if (cache != nullptr) {
    cache->h = h;
    cache->a = a;
    cache->p_in = Z.bottomRows(d);
  }
  core.flow(theta.head(nc), q, p, h, cache != nullptr ? &cache->core : nullptr);
  if (cache != nullptr) cache->p_core = p;
  Matrix out(2 * d, Z.cols());
  out.topRows(d) = q;
  out.bottomRows(d) = (p.array().rowwise() * a.transpose().array()).matrix();
  return out;
}

double abs_slope(double beta) {
  if (beta > 0.0) return 1.0;
  if (beta < 0.0) return -1.0;
  return 0.0;
}

// The previous CSympNetId::backward, verbatim but for the core accessor and where it reads.
void reference_backward(const CSympNetId& m, ConstParams theta, const Recorded& cache,
                        const Matrix& dZout, ParamsRef grad, Matrix* dZin) {
  const SymplecticCore& core = m.core();
  const Index d = core.d();
  const Index nc = core.n_params();
  const Vector& h = cache.h;
  const Vector& a = cache.a;
  const auto arow = a.transpose().array();
  Matrix gq = dZout.topRows(d);
  Matrix gp = dZout.bottomRows(d);
  Vector grad_a = (gp.array() * cache.p_core.array()).colwise().sum().transpose();
  gp.array().rowwise() *= arow;
  core.flow_backward(theta.head(nc), cache.core, h, gq, gp, grad.head(nc));
  grad_a.array() += (gp.array() * cache.p_in.array()).colwise().sum().transpose();
  grad(nc) += -0.5 * abs_slope(theta(nc)) * (grad_a.array() * h.array() * a.array()).sum();
  if (dZin != nullptr) {
    gp.array().rowwise() *= arow;
    dZin->resize(2 * d, dZout.cols());
    dZin->topRows(d) = gq;
    dZin->bottomRows(d) = gp;
  }
}

enum class Beta { kPositive, kNegative, kZero, kLarge };

struct RowsProblem {
  Vector theta, h, grad0;
  Matrix z, g;
};

RowsProblem random_rows_problem(const CSympNetId& m, Index n, Beta beta, std::mt19937_64& gen) {
  std::normal_distribution<double> normal;
  auto fill = [&](auto& x, double scale) {
    for (Index i = 0; i < x.size(); ++i) x.data()[i] = scale * normal(gen);
  };
  RowsProblem pr;
  pr.theta.resize(m.n_params());
  fill(pr.theta, 0.5);
  double& b = pr.theta(m.n_params() - 1);
  switch (beta) {
    case Beta::kPositive:
      b = 0.05 + std::abs(b);
      break;
    case Beta::kNegative:
      b = -0.05 - std::abs(b);
      break;
    case Beta::kZero:
      b = 0.0;
      break;
    // γ̂ h / 2 beyond 700 for the larger steps: those exps go to Eigen's own routine.
    case Beta::kLarge:
      b = -5000.0;
      break;
  }
  pr.h.resize(n);
  for (Index j = 0; j < n; ++j) pr.h(j) = 0.01 + 0.3 * std::abs(normal(gen));
  pr.z.resize(m.dim(), n);
  pr.g.resize(m.dim(), n);
  fill(pr.z, 1.0);
  fill(pr.g, 1.0);
  pr.grad0.resize(m.n_params());
  fill(pr.grad0, 0.1);
  return pr;
}

// Forward (with and without a cache, and again on a reused cache), backward with and without
// dZin, against the reference.
void expect_same_as_reference(const CSympNetId& m, Index n, Beta beta, std::mt19937_64& gen) {
  SCOPED_TRACE(m.hyperparams().dump() + ", N = " + std::to_string(n) +
               ", beta case = " + std::to_string(static_cast<int>(beta)));
  const RowsProblem pr = random_rows_problem(m, n, beta, gen);

  Recorded ref_cache;
  const Matrix ref_out = reference_forward(m, pr.theta, pr.z, pr.h, &ref_cache);
  Vector ref_grad = pr.grad0;
  Matrix ref_dz;
  reference_backward(m, pr.theta, ref_cache, pr.g, ref_grad, &ref_dz);
  Vector ref_grad_only = pr.grad0;
  reference_backward(m, pr.theta, ref_cache, pr.g, ref_grad_only, nullptr);
  ASSERT_TRUE(ref_out.allFinite() && ref_grad.allFinite());

  EXPECT_TRUE(same_bits(m.forward(pr.theta, pr.z, pr.h, nullptr), ref_out));

  // A cache that already holds a pass of another size and other parameters: its storage is
  // reused, which must not leak into the results.
  ForwardCache cache;
  const RowsProblem other = random_rows_problem(m, n + 3, Beta::kPositive, gen);
  m.forward(other.theta, other.z, other.h, &cache);
  for (int pass = 0; pass < 2; ++pass) {
    SCOPED_TRACE("pass " + std::to_string(pass));
    EXPECT_TRUE(same_bits(m.forward(pr.theta, pr.z, pr.h, &cache), ref_out));
    // h, a = exp(−γ̂h/2), p_in, p_core, then the core's records.
    const std::vector<Matrix> recorded = csympnet_records(m, cache);
    const std::vector<Matrix> expected = records_of(m, ref_cache);
    ASSERT_EQ(recorded.size(), expected.size());
    for (std::size_t i = 0; i < expected.size(); ++i) {
      EXPECT_TRUE(same_bits(recorded[i], expected[i])) << "record " << i;
    }
    Vector grad = pr.grad0;
    Matrix dz;
    m.backward(pr.theta, cache, pr.g, grad, &dz);
    EXPECT_TRUE(same_bits(grad, ref_grad));
    EXPECT_TRUE(same_bits(dz, ref_dz));
    Vector grad_only = pr.grad0;
    m.backward(pr.theta, cache, pr.g, grad_only, nullptr);
    EXPECT_TRUE(same_bits(grad_only, ref_grad_only));
  }
}

const Index kBatches[] = {1, 2, 3, 7, 8, 9, 15, 16, 17, 79, 80, 81, 250};

TEST(CSympNetIdRows, LaCoreScalarMatchesPreviousCode) {
  std::mt19937_64 gen(20261123);
  for (const Index n : kBatches) {
    for (const Index step_terms : {1, 2}) {
      const CSympNetId m(std::make_unique<LaSympNet>(
          1, 1 + static_cast<Index>(gen() % 5), 1 + static_cast<Index>(gen() % 20), step_terms));
      expect_same_as_reference(m, n, Beta::kPositive, gen);
      expect_same_as_reference(m, n, Beta::kNegative, gen);
    }
  }
  // The paper's s1 core at its batch size.
  const CSympNetId s1(std::make_unique<LaSympNet>(1, 5, 20));
  for (const Beta beta : {Beta::kPositive, Beta::kNegative, Beta::kZero, Beta::kLarge}) {
    expect_same_as_reference(s1, 80, beta, gen);
    expect_same_as_reference(s1, 81, beta, gen);
  }
}

TEST(CSympNetIdRows, LaCoreMatrixMatchesPreviousCode) {
  std::mt19937_64 gen(7);
  for (const Index d : {2, 3, 5}) {
    for (const Index n : kBatches) {
      const CSympNetId m(std::make_unique<LaSympNet>(d, 2, 3, 1 + static_cast<Index>(n % 2)));
      expect_same_as_reference(m, n, n % 2 == 0 ? Beta::kPositive : Beta::kNegative, gen);
    }
    const CSympNetId m(std::make_unique<LaSympNet>(d, 2, 4));
    expect_same_as_reference(m, 40, Beta::kZero, gen);
    expect_same_as_reference(m, 41, Beta::kLarge, gen);
  }
}

TEST(CSympNetIdRows, GCoreMatchesPreviousCode) {
  std::mt19937_64 gen(11);
  for (const Index d : {1, 2, 3}) {
    for (const Index n : kBatches) {
      const CSympNetId m(std::make_unique<GSympNet>(d, 3, 6 + static_cast<Index>(n % 5)));
      expect_same_as_reference(m, n, n % 2 == 0 ? Beta::kNegative : Beta::kPositive, gen);
    }
    const CSympNetId m(std::make_unique<GSympNet>(d, 2, 5));
    expect_same_as_reference(m, 33, Beta::kZero, gen);
    expect_same_as_reference(m, 34, Beta::kLarge, gen);
  }
}

// The checks still run, with their messages, when the arguments are wrong.
TEST(CSympNetIdRows, WrongShapesStillThrow) {
  const CSympNetId m(std::make_unique<LaSympNet>(1, 2, 3));
  const Vector theta = Vector::Constant(m.n_params(), 0.1);
  const Matrix z = Matrix::Ones(2, 4);
  const Vector h = Vector::Constant(4, 0.1);
  EXPECT_THROW(m.forward(theta, Matrix::Ones(3, 4), h, nullptr), Error);
  EXPECT_THROW(m.forward(theta, z, Vector::Constant(5, 0.1), nullptr), Error);
  EXPECT_THROW(m.forward(Vector::Constant(3, 0.1), z, h, nullptr), Error);
  ForwardCache cache;
  Vector grad = Vector::Zero(m.n_params());
  EXPECT_THROW(m.backward(theta, cache, z, grad, nullptr), Error);  // nothing recorded
  m.forward(theta, z, h, &cache);
  EXPECT_THROW(m.backward(theta, cache, Matrix::Ones(2, 5), grad, nullptr), Error);
  Vector short_grad = Vector::Zero(2);
  EXPECT_THROW(m.backward(theta, cache, z, short_grad, nullptr), Error);
  try {
    m.forward(theta, Matrix::Ones(3, 4), h, nullptr);
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("expected 2d = 2"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace csympnet::testing
