// The SympNet cores' sweeps at d > 1 were rewritten as steps on column ranges
// (src/models/la_sympnet_sweeps.cpp, g_sympnet.cpp) so that an epoch can run on several
// threads (column_split.hpp). None of that may change a bit. This file keeps the previous
// sweeps, written as they were before the rewrite, and compares the new serial flow() and
// flow_backward() with them; then it compares the column-split passes (any ranges, any number
// of shares) with the serial ones, for LA and G cores, with and without step polynomials,
// d from 2 to 12, batch sizes odd and even.
#include <gtest/gtest.h>

#include <memory>
#include <random>

#include "../src/models/activation.hpp"
#include "../src/models/core_product.hpp"
#include "../src/models/csympnet_id.hpp"
#include "../src/models/g_sympnet.hpp"
#include "../src/models/la_sympnet.hpp"
#include "support/flow_records.hpp"
#include "support/random_data.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

// θ offsets of LaSympNet (its documented layout).
struct LaLayout {
  Index d, layers, sublayers;
  bool poly;
  Index module(Index k) const { return k * (sublayers * d * d + 3 * d); }
  Index n_layer() const { return layers * (sublayers * d * d + 2 * d) + (layers - 1) * d; }
  Index shear_coef(Index k, Index i) const { return n_layer() + k * sublayers + i; }
  Index act_coef(Index k) const { return n_layer() + layers * sublayers + k; }
};

LaLayout layout_of(const LaSympNet& core) {
  return {core.d(), core.layers(), core.sublayers(), core.step_terms() == 2};
}

Vector core_step_of(const LaLayout& l, ConstParams theta, Index coef, const Vector& h) {
  if (!l.poly) return h;
  return (h.array() * (1.0 + theta(coef) * h.array())).matrix();
}

void symmetric(ConstParams theta, Index off, Index d, Matrix& s) {
  const Eigen::Map<const Matrix> a(theta.data() + off, d, d);
  s = a + a.transpose();
}

// The previous LaSympNet::flow at d > 1 (cache slots from 0), verbatim but for the layout.
void reference_la_flow(const LaSympNet& core, ConstParams theta, Matrix& q, Matrix& p,
                       const Vector& h, std::vector<Matrix>& cache) {
  const LaLayout l = layout_of(core);
  const Index dd = l.d;
  Matrix s(dd, dd), inc(dd, q.cols()), sig;
  cache.clear();
  for (Index k = 0; k < l.layers; ++k) {
    Index off = l.module(k);
    for (Index i = 0; i < l.sublayers; ++i, off += dd * dd) {
      const bool kick = i % 2 == 0;
      const Matrix& src = kick ? q : p;
      Matrix& dst = kick ? p : q;
      cache.push_back(src);
      symmetric(theta, off, dd, s);
      const Vector tau = core_step_of(l, theta, l.shear_coef(k, i), h);
      detail::core_product_add_scaled(s, src, tau.data(), dst, inc);
    }
    p.noalias() += theta.segment(off, dd) * h.transpose();
    q.noalias() += theta.segment(off + dd, dd) * h.transpose();
    if (k + 1 < l.layers) {
      const bool kick = k % 2 == 0;
      const Matrix& src = kick ? q : p;
      Matrix& dst = kick ? p : q;
      sigmoid_into(src, sig);
      cache.push_back(sig);
      const auto a = theta.segment(off + 2 * dd, dd).array();
      const Vector tau = core_step_of(l, theta, l.act_coef(k), h);
      dst.array() += (sig.array().colwise() * a).rowwise() * tau.transpose().array();
    }
  }
}

// The previous LaSympNet::flow_backward at d > 1, verbatim but for the layout.
void reference_la_backward(const LaSympNet& core, ConstParams theta,
                           const std::vector<Matrix>& cache, const Vector& h, Matrix& gq,
                           Matrix& gp, ParamsRef grad) {
  const LaLayout l = layout_of(core);
  const Index dd = l.d;
  Matrix s(dd, dd), gh(dd, gq.cols()), sg(dd, gq.cols()), outer(dd, dd);
  const Vector h2 = l.poly ? Vector(h.array().square()) : Vector();
  std::size_t slot = cache.size();
  for (Index k = l.layers - 1; k >= 0; --k) {
    const Index base = l.module(k);
    const Index bias = base + l.sublayers * dd * dd;
    if (k + 1 < l.layers) {
      const bool kick = k % 2 == 0;
      Matrix& gsrc = kick ? gq : gp;
      const Matrix& gdst = kick ? gp : gq;
      const Matrix& sig = cache[--slot];
      const auto a = theta.segment(bias + 2 * dd, dd).array();
      if (l.poly)
        grad(l.act_coef(k)) +=
            ((gdst.array() * sig.array()).colwise() * a).colwise().sum().matrix().dot(h2);
      gh = (gdst.array().rowwise() * core_step_of(l, theta, l.act_coef(k), h).transpose().array())
               .matrix();
      grad.segment(bias + 2 * dd, dd).array() += (gh.array() * sig.array()).rowwise().sum();
      gsrc.array() += (gh.array() * sig.array() * (1.0 - sig.array())).colwise() * a;
    }
    grad.segment(bias, dd).noalias() += gp * h;
    grad.segment(bias + dd, dd).noalias() += gq * h;
    for (Index i = l.sublayers - 1; i >= 0; --i) {
      const bool kick = i % 2 == 0;
      Matrix& gsrc = kick ? gq : gp;
      const Matrix& gdst = kick ? gp : gq;
      const Matrix& src = cache[--slot];
      const Index off = base + i * dd * dd;
      symmetric(theta, off, dd, s);
      if (l.poly)
        grad(l.shear_coef(k, i)) +=
            (gdst.array() * (s * src).array()).colwise().sum().matrix().dot(h2);
      gh = (gdst.array().rowwise() *
            core_step_of(l, theta, l.shear_coef(k, i), h).transpose().array())
               .matrix();
      detail::core_product(gh, src.transpose(), outer);
      Eigen::Map<Matrix> ga(grad.data() + off, dd, dd);
      ga += outer + outer.transpose();
      detail::core_product_add(s, gh, gsrc, sg);
    }
  }
}

// The previous GSympNet::flow and flow_backward, verbatim but for the layout.
void reference_g_flow(const GSympNet& core, ConstParams theta, Matrix& q, Matrix& p,
                      const Vector& h, std::vector<Matrix>& cache) {
  const Index dd = core.d(), w = core.width(), n = q.cols();
  Matrix u(w, n), sig, inc(dd, n);
  cache.clear();
  for (Index k = 0; k < core.layers(); ++k) {
    const Index off = k * w * (dd + 2);
    const Eigen::Map<const Matrix> kmat(theta.data() + off, w, dd);
    const auto a = theta.segment(off + w * dd, w).array();
    const auto b = theta.segment(off + w * (dd + 1), w).array();
    const bool kick = k % 2 == 0;
    const Matrix& src = kick ? q : p;
    Matrix& dst = kick ? p : q;
    cache.push_back(src);
    detail::core_product(kmat, src, u);
    u.array().colwise() += b;
    sigmoid_into(u, sig);
    cache.push_back(sig);
    u.array() = (sig.array().colwise() * a).rowwise() * h.transpose().array();
    detail::core_product_add(kmat.transpose(), u, dst, inc);
  }
}

void reference_g_backward(const GSympNet& core, ConstParams theta, const std::vector<Matrix>& cache,
                          const Vector& h, Matrix& gq, Matrix& gp, ParamsRef grad) {
  const Index dd = core.d(), w = core.width(), n = gq.cols();
  Matrix gh(dd, n), gy(w, n), y(w, n), gk(w, dd), gsrc_inc(dd, n);
  std::size_t slot = cache.size();
  for (Index k = core.layers() - 1; k >= 0; --k) {
    const Index off = k * w * (dd + 2);
    const Eigen::Map<const Matrix> kmat(theta.data() + off, w, dd);
    const auto a = theta.segment(off + w * dd, w).array();
    Eigen::Map<Matrix> grad_k(grad.data() + off, w, dd);
    const bool kick = k % 2 == 0;
    Matrix& gsrc = kick ? gq : gp;
    const Matrix& gdst = kick ? gp : gq;
    const Matrix& sig = cache[--slot];
    const Matrix& src = cache[--slot];
    gh = (gdst.array().rowwise() * h.transpose().array()).matrix();
    y = (sig.array().colwise() * a).matrix();
    detail::core_product_add(y, gh.transpose(), grad_k, gk);
    detail::core_product(kmat, gh, gy);
    grad.segment(off + w * dd, w).array() += (gy.array() * sig.array()).rowwise().sum();
    gy.array() = (gy.array() * sig.array() * (1.0 - sig.array())).colwise() * a;
    grad.segment(off + w * (dd + 1), w) += gy.rowwise().sum();
    detail::core_product_add(gy, src.transpose(), grad_k, gk);
    detail::core_product_add(kmat.transpose(), gy, gsrc, gsrc_inc);
  }
}

// θ large enough that the sweeps do real work (the documented init is 0.01).
Vector random_core_theta(std::mt19937_64& gen, Index n) {
  return random_matrix(gen, n, 1, 0.3).col(0);
}

Vector random_core_steps(std::mt19937_64& gen, Index n) {
  std::uniform_real_distribution<double> u(0.05, 0.15);
  Vector h(n);
  for (Index j = 0; j < n; ++j) h(j) = u(gen);
  return h;
}

struct CoreCase {
  std::string name;
  std::function<std::unique_ptr<SymplecticCore>()> make;
};

std::vector<CoreCase> core_cases() {
  std::vector<CoreCase> cases;
  for (Index d : {2, 3, 5, 8, 10, 12}) {
    for (Index poly : {1, 2}) {
      cases.push_back({"la d=" + std::to_string(d) + " terms=" + std::to_string(poly),
                       [=] { return std::make_unique<LaSympNet>(d, 3, 4, poly); }});
    }
  }
  cases.push_back({"la d=10 L=4 m=10", [] { return std::make_unique<LaSympNet>(10, 4, 10); }});
  for (Index d : {2, 3, 10}) {
    for (Index w : {5, 12, 50}) {
      cases.push_back({"g d=" + std::to_string(d) + " w=" + std::to_string(w),
                       [=] { return std::make_unique<GSympNet>(d, 3, w); }});
    }
  }
  return cases;
}

const Index kCoreBatches[] = {1, 2, 7, 16, 33, 81, 400};

TEST(CoreColumns, SerialSweepsEqualThePreviousSweeps) {
  std::mt19937_64 gen(31);
  for (const CoreCase& c : core_cases()) {
    const auto core = c.make();
    for (Index n : kCoreBatches) {
      SCOPED_TRACE(c.name + " N=" + std::to_string(n));
      const Index d = core->d();
      const Vector theta = random_core_theta(gen, core->n_params());
      const Vector h = random_core_steps(gen, n);
      const Matrix q0 = random_matrix(gen, d, n, 1.0), p0 = random_matrix(gen, d, n, 1.0);
      Matrix q_ref = q0, p_ref = p0, q = q0, p = p0;
      std::vector<Matrix> ref_cache;
      const auto* la = dynamic_cast<const LaSympNet*>(core.get());
      const auto* g = dynamic_cast<const GSympNet*>(core.get());
      if (la != nullptr) reference_la_flow(*la, theta, q_ref, p_ref, h, ref_cache);
      if (g != nullptr) reference_g_flow(*g, theta, q_ref, p_ref, h, ref_cache);
      ForwardCache cache;
      core->flow(theta, q, p, h, &cache);
      ASSERT_TRUE(same_bits(q_ref, q));
      ASSERT_TRUE(same_bits(p_ref, p));
      const std::vector<const Matrix*> recorded = flow_records(*core, cache);
      ASSERT_EQ(ref_cache.size(), recorded.size());
      for (std::size_t s = 0; s < ref_cache.size(); ++s) {
        ASSERT_TRUE(same_bits(ref_cache[s], *recorded[s])) << "record " << s;
      }
      const Matrix gq0 = random_matrix(gen, d, n, 1.0), gp0 = random_matrix(gen, d, n, 1.0);
      Matrix gq_ref = gq0, gp_ref = gp0, gq = gq0, gp = gp0;
      Vector grad_ref = Vector::Zero(core->n_params()), grad = grad_ref;
      if (la != nullptr) reference_la_backward(*la, theta, ref_cache, h, gq_ref, gp_ref, grad_ref);
      if (g != nullptr) reference_g_backward(*g, theta, ref_cache, h, gq_ref, gp_ref, grad_ref);
      core->flow_backward(theta, cache, h, gq, gp, grad);
      EXPECT_TRUE(same_bits(gq_ref, gq));
      EXPECT_TRUE(same_bits(gp_ref, gp));
      EXPECT_TRUE(same_bits(grad_ref, grad));
    }
  }
}

// The column-split passes of CSympNet-ID, with the given ranges and shares, against its serial
// forward and backward.
void expect_split_equals_serial(const CSympNetId& model, const std::vector<Columns>& ranges,
                                int shares, std::mt19937_64& gen) {
  const Index n = ranges.back().end;
  const Vector theta = random_core_theta(gen, model.n_params());
  const Vector h = random_core_steps(gen, n);
  const Matrix z = random_matrix(gen, model.dim(), n, 1.0);
  const Matrix dz = random_matrix(gen, model.dim(), n, 1.0);
  ForwardCache serial;
  const Matrix out_serial = model.forward(theta, z, h, &serial);
  Vector grad_serial = Vector::Zero(model.n_params());
  model.backward(theta, serial, dz, grad_serial, nullptr);

  ForwardCache split;
  model.prepare(theta, h, split);
  Matrix out(model.dim(), n);
  // Ranges in reverse order: no range may depend on another having run first.
  for (auto r = ranges.rbegin(); r != ranges.rend(); ++r) {
    model.forward_columns(theta, z, split, out, *r);
  }
  ASSERT_TRUE(same_bits(out_serial, out));
  const std::vector<Matrix> serial_records = csympnet_records(model, serial);
  const std::vector<Matrix> split_records = csympnet_records(model, split);
  ASSERT_EQ(serial_records.size(), split_records.size());
  for (std::size_t s = 0; s < serial_records.size(); ++s) {
    ASSERT_TRUE(same_bits(serial_records[s], split_records[s])) << "record " << s;
  }
  for (auto r = ranges.rbegin(); r != ranges.rend(); ++r)
    model.backward_columns(theta, split, dz, *r);
  Vector grad = Vector::Zero(model.n_params());
  for (int s = shares - 1; s >= 0; --s) model.backward_params(theta, split, grad, {s, shares});
  model.backward_finish(theta, split, grad);
  EXPECT_TRUE(same_bits(grad_serial, grad));
}

// Whenever splits() accepts the ranges (the contract: column_split.hpp).
TEST(CoreColumns, SplitPassesEqualTheSerialPasses) {
  std::mt19937_64 gen(32);
  int compared = 0;
  for (const CoreCase& c : core_cases()) {
    const CSympNetId model(c.make(), 0.3);
    for (Index n : kCoreBatches) {
      for (int parts : {2, 3, 5}) {
        const auto ranges = column_ranges(n, parts);
        if (!model.splits(n, ranges)) continue;
        ++compared;
        for (int shares : {1, 2, 3}) {
          SCOPED_TRACE(c.name + " N=" + std::to_string(n) + " ranges=" +
                       std::to_string(ranges.size()) + " shares=" + std::to_string(shares));
          expect_split_equals_serial(model, ranges, shares, gen);
        }
      }
    }
  }
  // Where the exact kernels run, most of these cases split (all but d < 8 and tiny ranges).
  if (std::string(kernels::product_kernel_isa()) != "portable") {
    EXPECT_GE(compared, 120);
  }
}

// The split must be taken where it can be, or the comparisons above say nothing about the
// threaded epochs: with the exact kernels running, the presets' d = 10 cores and the d = 100
// one split their 400 pairs; a d = 1 core never splits.
TEST(CoreColumns, PresetCoresSplitWhereTheKernelsRun) {
  const CSympNetId s1(std::make_unique<LaSympNet>(1, 5, 20));
  EXPECT_FALSE(s1.splits(80, column_ranges(80, 2)));
  if (std::string(kernels::product_kernel_isa()) == "portable") GTEST_SKIP() << "no exact kernels";
  const CSympNetId s2(std::make_unique<LaSympNet>(10, 4, 10));
  const CSympNetId s3(std::make_unique<GSympNet>(10, 7, 50));
  const CSympNetId s2_100(std::make_unique<LaSympNet>(100, 4, 4));
  for (int parts : {2, 3, 4}) {
    EXPECT_TRUE(s2.splits(400, column_ranges(400, parts)));
    EXPECT_TRUE(s3.splits(400, column_ranges(400, parts)));
    EXPECT_TRUE(s2_100.splits(400, column_ranges(400, parts)));
  }
  // Ranges that do not start at multiples of kColumnAlign are refused.
  EXPECT_FALSE(s2.splits(400, {{0, 203}, {203, 400}}));
}

TEST(ColumnRanges, CoverTheBatchInAlignedNonEmptyBalancedRanges) {
  for (Index n : {0, 1, 7, 8, 9, 16, 17, 80, 100, 399, 400, 1001}) {
    for (int parts : {1, 2, 3, 7, 64}) {
      const auto r = column_ranges(n, parts);
      ASSERT_FALSE(r.empty());
      EXPECT_LE(static_cast<int>(r.size()), parts);
      EXPECT_EQ(r.front().begin, 0);
      EXPECT_EQ(r.back().end, n);
      Index smallest = n, largest = 0;
      for (std::size_t i = 0; i < r.size(); ++i) {
        EXPECT_EQ(r[i].begin % kColumnAlign, 0);
        if (i > 0) {
          EXPECT_EQ(r[i].begin, r[i - 1].end);
        }
        if (n > 0) {
          EXPECT_GE(r[i].size(), 1);
        }
        if (i + 1 < r.size()) {
          smallest = std::min(smallest, r[i].size());
          largest = std::max(largest, r[i].size());
        }
      }
      if (r.size() > 2) {
        EXPECT_LE(largest - smallest, kColumnAlign);
      }
      // As many ranges as there are aligned blocks to give, up to `parts`.
      const Index blocks = (n + kColumnAlign - 1) / kColumnAlign;
      EXPECT_EQ(static_cast<Index>(r.size()), std::max<Index>(1, std::min<Index>(parts, blocks)));
    }
  }
}

}  // namespace
}  // namespace csympnet::testing
