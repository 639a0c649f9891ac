#include "csympnet/train/shooting.hpp"
#include "csympnet/core/dense.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include "csympnet/core/error.hpp"
#include "csympnet/core/stop.hpp"
#include "lapack.hpp"

namespace csympnet {

const Matrix& ShootingSegments::inputs(Index s) const {
  static const Matrix kNone;
  return u.empty() ? kNone : u[static_cast<std::size_t>(s)];
}

Index ShootingSegments::n_rows() const {
  Index n = 0;
  for (const Matrix& x : q) n += x.size();
  return n;
}

Index ShootingSegments::observed_rows() const {
  return q.empty() ? d : q.front().rows();
}

Index ShootingSegments::n_residuals() const {
  if (observed.empty()) return n_rows();
  double n = 0.0;
  const auto o = static_cast<double>(observed_rows());
  for (std::size_t s = 0; s < q.size(); ++s) n += o * observed[s].sum();
  return static_cast<Index>(std::llround(n));
}

void ShootingSegments::validate(const std::string& where) const {
  require(d >= 1, [&] { return where + ": d must be >= 1"; });
  require(h.size() == q.size() && block.size() == q.size(),
          [&] { return where + ": need steps and a block for every segment"; });
  for (std::size_t s = 0; s < q.size(); ++s) {
    const std::string at = where + ": segment " + std::to_string(s);
    require((q[s].rows() == d || q[s].rows() == 2 * d) && q[s].rows() == q.front().rows() &&
                q[s].cols() >= 2,
            [&] {
              return at +
                     ": expected d x L positions (or 2d x L states, the same in every segment) "
                     "with L >= 2";
            });
    require(h[s].size() == q[s].cols() - 1, [&] { return at + ": expected L - 1 steps"; });
    require(q[s].allFinite() && h[s].allFinite(), [&] { return at + ": non-finite value"; });
    require((h[s].array() > 0.0).all(), [&] { return at + ": every step must be > 0"; });
    require(block[s] >= 0, [&] { return at + ": block indices must be >= 0"; });
    if (!observed.empty())
      require(observed[s].size() == q[s].cols() &&
                  (observed[s].array() == 0.0 || observed[s].array() == 1.0).all(),
              [&] { return at + ": expected one weight, 0 or 1, per position"; });
    if (!column_block.empty())
      require(static_cast<Index>(column_block[s].size()) == q[s].cols() &&
                  std::all_of(column_block[s].begin(), column_block[s].end(),
                              [](Index b) { return b >= 0; }),
              [&] { return at + ": expected one block index >= 0 per position"; });
  }
  require(row_weight.size() == 0 || (row_weight.size() == observed_rows() &&
                                     row_weight.allFinite() && (row_weight.array() > 0.0).all()),
          [&] { return where + ": expected one positive weight per observed row, or none"; });
  require(observed.empty() || observed.size() == q.size(),
          [&] { return where + ": need weights for every segment or none"; });
  require(column_block.empty() || column_block.size() == q.size(),
          [&] { return where + ": need position blocks for every segment or none"; });
  require(u.empty() || u.size() == q.size(),
          [&] { return where + ": need inputs for every segment or none"; });
  for (std::size_t s = 0; s < u.size(); ++s)
    require(u[s].rows() > 0 && u[s].rows() % 2 == 0 && u[s].rows() == u.front().rows() &&
                u[s].cols() == q[s].cols() - 1 && u[s].allFinite(),
            [&] {
              return where + ": segment " + std::to_string(s) +
                     ": expected 2m x (L - 1) finite inputs, the same m in every segment";
            });
}

Matrix shooting_states(const OneStepMap& map, ConstParams theta, const Vector& z0, const Vector& h,
                       const Matrix& u) {
  Matrix z(z0.size(), h.size() + 1);
  z.col(0) = z0;
  if (map.has_step_tangents()) {
    // The same bits as forward_driven(), without a batch's allocations per step.
    Matrix none(z0.size(), 0);
    Vector zk = z0;
    for (Index k = 0; k < h.size(); ++k) {
      map.step_tangents(theta, h(k), u.rows() > 0 ? u.col(k).data() : nullptr, zk.data(), none, 0);
      z.col(k + 1) = zk;
    }
    return z;
  }
  Vector step(1);
  for (Index k = 0; k < h.size(); ++k) {
    step(0) = h(k);
    if (u.rows() == 0)
      z.col(k + 1) = map.apply(theta, z.col(k), step);
    else
      z.col(k + 1) = map.forward_driven(theta, z.col(k), step, u.col(k), nullptr);
  }
  return z;
}

namespace {

// r = P z − q (P: the observed rows of the state, the positions or all of it), as one column
// per position flattened position-major; each column times its weight w, each row times its
// row weight rw (empty: all 1).
Vector position_residuals(const Matrix& z, const Matrix& q, const Vector& w = Vector(),
                          const Vector& rw = Vector()) {
  Matrix r = z.topRows(q.rows()) - q;
  if (w.size() > 0) r *= w.asDiagonal();
  if (rw.size() > 0) r = rw.asDiagonal() * r;
  return Eigen::Map<const Vector>(r.data(), r.size());
}

const Vector& weights_of(const ShootingSegments& segs, std::size_t s) {
  static const Vector kNone;
  return segs.observed.empty() ? kNone : segs.observed[s];
}

// DΦ̂ at step k of a segment, driven by its inputs u (empty: none).
Matrix step_jacobian(const OneStepMap& map, ConstParams theta, const Matrix& z, const Vector& h,
                     const Matrix& u, Index k) {
  if (u.rows() == 0) return map.jacobian(theta, z.col(k), h(k));
  return map.jacobian_driven(theta, z.col(k), h(k), u.col(k));
}

// A driven segment's rollout from z0 over the steps h with inputs u into z (2d × L, L − 1 =
// h.size(), as shooting_states), with ∂Φ̂/∂θ at each of its first L − 1 states into g
// ((L − 1)·2d × P, row k·2d + i the i-th component of step k): one reverse pass per component.
// The same passes give each step's DΦ̂ (row i of step k's is the pass's ∂Φ̂_i/∂z) into jacs
// (2d × (L − 1)·2d, step k's in columns k·2d … k·2d + 2d − 1).
void driven_segment_rows(const OneStepMap& map, ConstParams theta, const Vector& z0,
                         const Vector& h, const Matrix& u, Matrix& z, RowMajorMatrix& g,
                         Matrix& jacs) {
  const Index dim = z0.size(), steps = h.size(), p = map.n_params();
  z.resize(dim, steps + 1);
  z.col(0) = z0;
  g.setZero(steps * dim, p);
  jacs.resize(dim, steps * dim);
  ForwardCache cache;
  Vector step(1), grad(p);
  Matrix bar(dim, 1), dz;
  for (Index k = 0; k < steps; ++k) {
    step(0) = h(k);
    z.col(k + 1) = map.forward_driven(theta, z.col(k), step, u.col(k), &cache);
    for (Index i = 0; i < dim; ++i) {
      bar.setZero();
      bar(i, 0) = 1.0;
      grad.setZero();
      map.backward(theta, cache, bar, grad, &dz);
      g.row(k * dim + i) = grad.transpose();
      jacs.block(i, k * dim, 1, dim) = dz.col(0).transpose();
    }
  }
}

// B = ∂r/∂z0 along one segment (the T recursion alone), from its rollout z (2d × L).
void start_state_jacobian(const OneStepMap& map, ConstParams theta, const Matrix& z,
                          const Matrix& q, const Vector& h, const Vector& w, const Vector& rw,
                          Matrix& b, const Matrix& u) {
  const Index o = q.rows(), len = q.cols(), dim = z.rows();
  b.resize(len * o, dim);
  Matrix t = Matrix::Identity(dim, dim);
  const bool tangents = map.has_step_tangents();
  Vector zk(dim);
  for (Index k = 0; k < len; ++k) {
    b.middleRows(k * o, o) = t.topRows(o);
    if (rw.size() > 0) b.middleRows(k * o, o) = rw.asDiagonal() * b.middleRows(k * o, o);
    if (w.size() > 0) b.middleRows(k * o, o) *= w(k);
    if (k + 1 == len) break;
    if (tangents) {
      zk = z.col(k);
      map.step_tangents(theta, h(k), u.rows() > 0 ? u.col(k).data() : nullptr, zk.data(), t, 0);
    } else {
      t = step_jacobian(map, theta, z, h, u, k) * t;
    }
  }
}

// A segment's rollout from z0 (2d × L) and B = ∂r/∂z0 in one forward-mode pass, for a map with
// step_tangents(): the states have shooting_states()' bits and B start_state_jacobian()'s.
void rollout_with_start_jacobian(const OneStepMap& map, ConstParams theta, const Vector& z0,
                                 const Matrix& q, const Vector& h, const Vector& w,
                                 const Vector& rw, const Matrix& u, Matrix& states, Matrix& b) {
  const Index o = q.rows(), len = q.cols(), dim = z0.size();
  states.resize(dim, len);
  states.col(0) = z0;
  b.resize(len * o, dim);
  Matrix t = Matrix::Identity(dim, dim);
  Vector zk = z0;
  for (Index k = 0; k < len; ++k) {
    b.middleRows(k * o, o) = t.topRows(o);
    if (rw.size() > 0) b.middleRows(k * o, o) = rw.asDiagonal() * b.middleRows(k * o, o);
    if (w.size() > 0) b.middleRows(k * o, o) *= w(k);
    if (k + 1 == len) break;
    map.step_tangents(theta, h(k), u.rows() > 0 ? u.col(k).data() : nullptr, zk.data(), t, 0);
    states.col(k + 1) = zk;
  }
}

// shooting_segment_jacobian's rows by forward-mode sensitivities (OneStepMap::step_tangents):
// one pass along the segment carries T = ∂z_k/∂(θ_free, z₀) (2d × (n_free + 2d)); A's rows are
// T's first n_free columns at the observed rows, B's its last 2d.
void tangent_segment_rows(const OneStepMap& map, ConstParams theta, const Vector& z0,
                          const Matrix& q, const Vector& h, Index n_free, RowMajorMatrix& a,
                          Matrix& b, Vector& r, const Vector& w, const Matrix& u,
                          const Vector& rw) {
  const Index o = q.rows(), len = q.cols(), dim = z0.size();
  a.resize(len * o, n_free);
  b.resize(len * o, dim);
  r.resize(len * o);
  Matrix t = Matrix::Zero(dim, n_free + dim);
  t.rightCols(dim).setIdentity();
  Vector z = z0;
  for (Index k = 0; k < len; ++k) {
    const double wk = w.size() > 0 ? w(k) : 1.0;
    for (Index i = 0; i < o; ++i) {
      const double s = rw.size() > 0 ? wk * rw(i) : wk;
      const Index row = k * o + i;
      a.row(row) = s * t.block(i, 0, 1, n_free);
      b.row(row) = s * t.block(i, n_free, 1, dim);
      // As position_residuals: (z − q) times the column's weight, then the row's.
      double res = z(i) - q(i, k);
      if (w.size() > 0) res *= wk;
      if (rw.size() > 0) res = rw(i) * res;
      r(row) = res;
    }
    if (k + 1 == len) break;
    map.step_tangents(theta, h(k), u.rows() > 0 ? u.col(k).data() : nullptr, z.data(), t, n_free);
  }
}

// U⁻¹ for a small symmetric positive semi-definite U; a ridge at rounding level only where U is
// singular or nearly so (condition beyond 1e14), so that a segment whose positions do not
// determine its start state still solves.
dense::Llt small_factor(const Matrix& u) {
  const double top = std::max(u.diagonal().maxCoeff(), 1e-300);
  dense::Llt f(u);
  if (f.ok() && f.factor_diagonal().minCoeff() > 1e-7 * std::sqrt(top)) return f;
  return dense::Llt(u + 1e-14 * top * Matrix::Identity(u.rows(), u.cols()));
}

}  // namespace

Vector shooting_residuals(const OneStepMap& map, ConstParams theta, const Matrix& z0,
                          const ShootingSegments& segs) {
  Vector out(segs.n_rows());
  Index at = 0;
  for (Index s = 0; s < segs.size(); ++s) {
    const auto& q = segs.q[static_cast<std::size_t>(s)];
    const Matrix z =
        shooting_states(map, theta, z0.col(s), segs.h[static_cast<std::size_t>(s)], segs.inputs(s));
    out.segment(at, q.size()) =
        position_residuals(z, q, weights_of(segs, static_cast<std::size_t>(s)), segs.row_weight);
    at += q.size();
  }
  return out;
}

double shooting_loss(const OneStepMap& map, ConstParams theta, const Matrix& z0,
                     const ShootingSegments& segs) {
  const Vector r = shooting_residuals(map, theta, z0, segs);
  const Index n = segs.n_residuals();
  return n > 0 ? r.squaredNorm() / static_cast<double>(n) : 0.0;
}

void shooting_segment_jacobian(const OneStepMap& map, ConstParams theta, const Vector& z0,
                               const Matrix& q, const Vector& h, Index n_free, RowMajorMatrix& a,
                               Matrix& b, Vector& r, const Vector& w, const Matrix& u,
                               const Vector& rw) {
  const Index o = q.rows(), len = q.cols(), dim = map.dim(), p = map.n_params();
  require(n_free >= 0 && n_free <= p, "shooting: n_free out of range");
  require(w.size() == 0 || w.size() == len, "shooting: expected one weight per position");
  require(z0.size() == dim && (2 * o == dim || o == dim),
          "shooting: expected the positions or the whole state observed");
  require(rw.size() == 0 || rw.size() == o, "shooting: expected one weight per observed row");
  if (map.has_step_tangents()) {
    tangent_segment_rows(map, theta, z0, q, h, n_free, a, b, r, w, u, rw);
    return;
  }
  // ∂Φ̂/∂θ at each state of the segment but the last: one-step windows (their residuals unused);
  // driven, with the rollout and each step's DΦ̂ from the same passes.
  RowMajorMatrix g;
  Matrix z, driven_jacs;
  const bool driven = len > 1 && u.rows() > 0;
  if (driven)
    driven_segment_rows(map, theta, z0, h, u, z, g, driven_jacs);
  else
    z = shooting_states(map, theta, z0, h, u);
  r = position_residuals(z, q, w, rw);
  a.setZero(len * o, n_free);
  b.resize(len * o, dim);
  if (!driven && len > 1) {
    WindowSet steps;
    steps.m = 1;
    steps.z0 = z.leftCols(len - 1);
    steps.zm = Matrix::Zero(dim, len - 1);
    steps.h = h.transpose();
    g.resize((len - 1) * dim, p);
    Vector unused((len - 1) * dim);
    window_jacobian_rows(map, theta, steps, false, 0, len - 1, g, unused);
  }
  // The recursions sens ← DΦ̂·sens + ∂Φ̂/∂θ and T ← DΦ̂·T, into second buffers swapped in (no
  // allocation per step).
  Matrix sens = Matrix::Zero(dim, n_free), sens_next(dim, n_free);
  Matrix t = Matrix::Identity(dim, dim), t_next(dim, dim);
  Matrix jac;
  for (Index k = 0; k < len; ++k) {
    const double wk = w.size() > 0 ? w(k) : 1.0;
    a.middleRows(k * o, o) = wk * sens.topRows(o);
    b.middleRows(k * o, o) = wk * t.topRows(o);
    if (rw.size() > 0) {
      a.middleRows(k * o, o) = rw.asDiagonal() * a.middleRows(k * o, o);
      b.middleRows(k * o, o) = rw.asDiagonal() * b.middleRows(k * o, o);
    }
    if (k + 1 == len) break;
    if (driven)
      jac = driven_jacs.middleCols(k * dim, dim);
    else
      jac = step_jacobian(map, theta, z, h, u, k);
    sens_next.noalias() = jac * sens;
    sens_next += g.block(k * dim, 0, dim, n_free);
    sens.swap(sens_next);
    t_next.noalias() = jac * t;
    t.swap(t_next);
  }
}

namespace {

// What one segment contributes to the normal equations, kept for the Schur complement.
struct SegmentTerms {
  Matrix u;   // BᵀB (2d × 2d)
  Matrix w;   // AᵀB (n_free × 2d)
  Vector gb;  // Bᵀr
  // With scores, for a segment spanning several blocks: (block, B_bᵀr_b) over its positions in
  // each block (empty: the whole gb is the segment's block's).
  std::vector<std::pair<Index, Vector>> gb_by_block;
};

// For each block's information (block_information): what the rows of one block inside one
// segment contribute (A_bᵀB_b, B_bᵀB_b), and per block its Σ A_bᵀA_b.
struct BlockPiece {
  Index segment = 0, block = 0;
  Matrix w, u;
};
struct BlockPieces {
  std::vector<Matrix> gram;  // per block, n_free × n_free (full)
  std::vector<BlockPiece> pieces;
};

// Rows [k·d, (k+1)·d) of a segment belong to position k: the runs of positions in one block.
template <class F>
void for_each_block_run(const ShootingSegments& segs, Index s, Index len, F f) {
  for (Index k = 0; k < len;) {
    const Index b = segs.block_of(s, k);
    Index e = k + 1;
    while (e < len && segs.block_of(s, e) == b) ++e;
    f(b, k, e);
    k = e;
  }
}

// Σ AᵀA (lower) and Σ Aᵀr into ne.a, ne.g, the per-segment terms into `terms`, the cost, and
// per block Aᵀr (the efficient score is completed in reduce()).
NormalEquations accumulate(const OneStepMap& map, ConstParams theta, const Matrix& z0,
                           const ShootingSegments& segs, Index n_free, double scale,
                           bool with_scores, const std::function<bool()>& should_stop,
                           std::vector<SegmentTerms>& terms, BlockPieces* jk = nullptr) {
  NormalEquations ne;
  ne.a.setZero(n_free, n_free);
  ne.g.setZero(n_free);
  Index blocks = 0;
  for (Index b : segs.block) blocks = std::max(blocks, b + 1);
  for (const auto& cb : segs.column_block)
    for (Index b : cb) blocks = std::max(blocks, b + 1);
  if (with_scores) ne.scores.setZero(n_free, blocks);
  if (jk != nullptr) {
    jk->gram.assign(static_cast<std::size_t>(blocks), Matrix::Zero(n_free, n_free));
    jk->pieces.clear();
  }
  terms.assign(static_cast<std::size_t>(segs.size()), {});
  const lapack::SingleThreaded one_thread;
  RowMajorMatrix a;
  Matrix b;
  Vector r;
  for (Index s = 0; s < segs.size(); ++s) {
    if (should_stop && should_stop()) {
      ne.stopped = true;
      return ne;
    }
    const auto i = static_cast<std::size_t>(s);
    shooting_segment_jacobian(map, theta, z0.col(s), segs.q[i], segs.h[i], n_free, a, b, r,
                              weights_of(segs, i), segs.inputs(s), segs.row_weight);
    a *= scale;
    b *= scale;
    r *= scale;
    ne.cost += 0.5 * r.squaredNorm();
    lapack::add_gram_from_transpose(a.data(), n_free, a.rows(), ne.a.data());
    Vector ar = Vector::Zero(n_free);
    lapack::add_transpose_times(a.data(), n_free, a.rows(), r.data(), ar.data());
    ne.g += ar;
    SegmentTerms& x = terms[i];
    x.u = b.transpose() * b;
    x.w.noalias() = a.transpose() * b;
    x.gb = b.transpose() * r;
    if (jk != nullptr) {
      const Index o = segs.observed_rows(), len = segs.q[i].cols();
      const auto add_piece = [&](Index blk, Index k0, Index k1) {
        const Index r0 = k0 * o, rows = (k1 - k0) * o;
        const auto ab = a.middleRows(r0, rows);
        const auto bb = b.middleRows(r0, rows);
        jk->gram[static_cast<std::size_t>(blk)].noalias() += ab.transpose() * ab;
        jk->pieces.push_back({s, blk, ab.transpose() * bb, bb.transpose() * bb});
      };
      if (segs.column_block.empty())
        add_piece(segs.block[i], 0, len);
      else
        for_each_block_run(segs, s, len, add_piece);
    }
    if (with_scores && segs.column_block.empty()) {
      ne.scores.col(segs.block[i]) += ar;
    } else if (with_scores) {
      const Index o = segs.observed_rows(), len = segs.q[i].cols();
      for_each_block_run(segs, s, len, [&](Index blk, Index k0, Index k1) {
        const Index rows = (k1 - k0) * o;
        ne.scores.col(blk).noalias() +=
            a.middleRows(k0 * o, rows).transpose() * r.segment(k0 * o, rows);
        x.gb_by_block.emplace_back(
            blk, b.middleRows(k0 * o, rows).transpose() * r.segment(k0 * o, rows));
      });
    }
  }
  return ne;
}

// Marquardt's scaling, the diagonal of JᵀJ clamped to [1e-6, 1e32] as Ceres clamps it
// (min/max_lm_diagonal): a parameter the data barely move still gets a damped step, not one
// that sends it to 1e40.
Vector marquardt_diagonal(const Matrix& a) {
  return a.diagonal().cwiseMax(1e-6).cwiseMin(1e32);
}

// The reduced system at damping λ (Marquardt's scaling on both blocks): a and g of the
// reduced normal equations; with scores, the efficient scores (λ = 0 only).
void reduce(NormalEquations& ne, const std::vector<SegmentTerms>& terms,
            const ShootingSegments& segs, double lambda, Matrix& a, Vector& g) {
  a = ne.a;
  g = ne.g;
  a.diagonal() += lambda * marquardt_diagonal(ne.a);
  // The segments' V are gathered side by side and subtracted kReduceBatch columns at a time:
  // one rank-2d update per segment spent most of this function's time in the update's own
  // overhead (a 146-parameter neural core, segments of 2 start-state columns).
  constexpr Index kReduceBatch = 256;
  Matrix batch(a.rows(), 0);
  Index used = 0;
  const auto flush = [&] {
    if (used == 0) return;
    a.selfadjointView<Eigen::Lower>().rankUpdate(batch.leftCols(used), -1.0);
    used = 0;
  };
  for (std::size_t i = 0; i < terms.size(); ++i) {
    const SegmentTerms& x = terms[i];
    Matrix u = x.u;
    u.diagonal() += lambda * marquardt_diagonal(x.u);
    const dense::Llt f = small_factor(u);
    // W U⁻¹ Wᵀ = V Vᵀ with V = W L⁻ᵀ.
    const Matrix v = f.lower_solve_transposed(x.w);
    if (batch.cols() == 0) batch.resize(a.rows(), std::max(kReduceBatch, v.cols()));
    if (used + v.cols() > batch.cols()) flush();
    batch.middleCols(used, v.cols()) = v;
    used += v.cols();
    const Vector ug = f.solve(x.gb);
    g.noalias() -= x.w * ug;
    if (ne.scores.size() == 0) continue;
    if (x.gb_by_block.empty()) {
      ne.scores.col(segs.block[i]).noalias() -= x.w * ug;
    } else {
      // The efficient score of the positions in block b: A_bᵀr_b − W U⁻¹ B_bᵀr_b.
      for (const auto& [blk, gbb] : x.gb_by_block)
        ne.scores.col(blk).noalias() -= x.w * f.solve(gbb);
    }
  }
  flush();
}

// The Moore–Penrose inverse of a small symmetric positive semi-definite U: eigenvalues below
// 1e-10 of the largest count as 0. Rows too few to fix a start state then carry no information
// on θ (A_kᵀ(I − P_B)A_k = 0), as they would once that start state is fitted to them.
Matrix small_pseudo_inverse(const Matrix& u) {
  const dense::SymmetricEigen e = dense::symmetric_eigen(u);
  const Vector& l = e.values;
  const double top = std::max(l.maxCoeff(), 0.0);
  Vector inv = Vector::Zero(l.size());
  for (Index k = 0; k < l.size(); ++k)
    if (l(k) > 1e-10 * top) inv(k) = 1.0 / l(k);
  return e.vectors * inv.asDiagonal() * e.vectors.transpose();
}

// The normal equations with the start states eliminated (accumulate, then reduce at λ = 0);
// `terms` keeps the segments' terms, `jk` (optional) each block's pieces.
NormalEquations reduced_equations(const OneStepMap& map, ConstParams theta, const Matrix& z0,
                                  const ShootingSegments& segs, Index n_free, double scale,
                                  bool with_scores, const std::function<bool()>& should_stop,
                                  std::vector<SegmentTerms>& terms, BlockPieces* jk = nullptr) {
  NormalEquations ne =
      accumulate(map, theta, z0, segs, n_free, scale, with_scores, should_stop, terms, jk);
  if (ne.stopped) return ne;
  Matrix a;
  Vector g;
  reduce(ne, terms, segs, 0.0, a, g);
  ne.a = std::move(a);
  ne.g = std::move(g);
  return ne;
}

// Per block b, the information on θ in its rows once every segment's start state is eliminated
// (the efficient Jacobian J̃_b = A_b − B_b U_s⁻¹ W_sᵀ over the segment's rows in the block):
//   E_b = Σ_{s∋b} (A_bᵀA_b − W_b U_s⁻¹ W_sᵀ − W_s U_s⁻¹ W_bᵀ + W_s U_s⁻¹ U_b U_s⁻¹ W_sᵀ),
// with W_b = A_bᵀB_b and U_b = B_bᵀB_b. Σ_b E_b is the reduced matrix Ã, and with independent
// noise of one variance block b's score has variance in proportion to uᵀE_b u
// (docs/derivations.md, "How many blocks an interval rests on").
std::vector<Matrix> block_information(const std::vector<SegmentTerms>& terms,
                                      const BlockPieces& jk) {
  std::vector<Matrix> e(jk.gram);
  std::vector<Matrix> u_inv(terms.size());
  for (std::size_t s = 0; s < terms.size(); ++s) u_inv[s] = small_pseudo_inverse(terms[s].u);
  for (const BlockPiece& p : jk.pieces) {
    const auto s = static_cast<std::size_t>(p.segment);
    const SegmentTerms& x = terms[s];
    const Matrix v = x.w * u_inv[s];  // W_s U_s⁻¹
    const Matrix cross = p.w * v.transpose();
    e[static_cast<std::size_t>(p.block)].noalias() +=
        v * p.u * v.transpose() - cross - cross.transpose();
  }
  return e;
}

}  // namespace

ShootingSegments split_blocks_into_runs(const ShootingSegments& segs, Index run) {
  require(run >= 1, "split_blocks_into_runs: run must be >= 1");
  ShootingSegments out = segs;
  std::map<Index, Index> seen;                  // per block, its positions so far
  std::map<std::pair<Index, Index>, Index> id;  // (block, run) → cluster
  out.column_block.assign(static_cast<std::size_t>(segs.size()), {});
  for (Index s = 0; s < segs.size(); ++s) {
    const auto i = static_cast<std::size_t>(s);
    const Index len = segs.q[i].cols();
    out.column_block[i].resize(static_cast<std::size_t>(len));
    for (Index k = 0; k < len; ++k) {
      const Index b = segs.block_of(s, k);
      const auto key = std::make_pair(b, seen[b]++ / run);
      const auto it = id.emplace(key, static_cast<Index>(id.size())).first;
      out.column_block[i][static_cast<std::size_t>(k)] = it->second;
    }
    out.block[i] = out.column_block[i].front();
  }
  return out;
}

NormalEquations shooting_block_equations(const OneStepMap& map, ConstParams theta, const Matrix& z0,
                                         const ShootingSegments& segs, Index n_free, double scale,
                                         const std::function<bool()>& should_stop) {
  segs.validate("shooting");
  Index blocks = 0;
  for (Index b : segs.block) blocks = std::max(blocks, b + 1);
  for (const auto& cb : segs.column_block)
    for (Index b : cb) blocks = std::max(blocks, b + 1);
  const bool feasible =
      static_cast<double>(blocks) * static_cast<double>(n_free) * static_cast<double>(n_free) <=
      kBlockInformationMaxNumbers;
  if (!feasible)
    return shooting_normal_equations(map, theta, z0, segs, n_free, scale, true, should_stop);
  BlockPieces jk;
  std::vector<SegmentTerms> terms;
  NormalEquations ne =
      reduced_equations(map, theta, z0, segs, n_free, scale, true, should_stop, terms, &jk);
  if (!ne.stopped) ne.block_information = block_information(terms, jk);
  return ne;
}

NormalEquations shooting_normal_equations(const OneStepMap& map, ConstParams theta,
                                          const Matrix& z0, const ShootingSegments& segs,
                                          Index n_free, double scale, bool with_scores,
                                          const std::function<bool()>& should_stop) {
  segs.validate("shooting");
  std::vector<SegmentTerms> terms;
  return reduced_equations(map, theta, z0, segs, n_free, scale, with_scores, should_stop, terms);
}

namespace {

// One segment's start state by Levenberg–Marquardt on its 2d unknowns, θ fixed, from z (updated
// in place), until an accepted step, or the Gauss–Newton step predicted, lowers ‖r‖² by at most
// `tolerance` of itself. Returns ‖r‖² after (infinite when no start gives a finite rollout). B is
// recomputed only when another step is taken, from the rollout the accepted trial already ran.
double fit_one_start(const OneStepMap& map, ConstParams theta, const Matrix& q, const Vector& h,
                     const Vector& w, const Vector& rw, Eigen::Ref<Vector> z, long iterations,
                     double max_abs, const Matrix& inputs, double tolerance) {
  // With step_tangents() each rollout carries B with it (one pass, not a rollout and then a
  // pass for B), so B is current after every accepted trial.
  const bool fused = map.has_step_tangents();
  Matrix states, b, b_try;
  if (fused)
    rollout_with_start_jacobian(map, theta, z, q, h, w, rw, inputs, states, b);
  else
    states = shooting_states(map, theta, z, h, inputs);
  Vector r = position_residuals(states, q, w, rw);
  double lambda = 1e-3;
  double cost = std::numeric_limits<double>::infinity();
  if (r.allFinite() && z.cwiseAbs().maxCoeff() <= max_abs) {
    if (!fused) start_state_jacobian(map, theta, states, q, h, w, rw, b, inputs);
    if (b.allFinite()) cost = r.squaredNorm();
  }
  bool b_current = true;  // b is B at z
  const double rounding =
      kRoundingShare * position_residuals(Matrix::Zero(q.rows(), q.cols()), q, w, rw).squaredNorm();
  for (long it = 0; it < iterations && std::isfinite(cost); ++it) {
    throw_if_stop_requested("the fit of a hidden start state");
    if (!b_current) start_state_jacobian(map, theta, states, q, h, w, rw, b, inputs);
    b_current = true;
    const Matrix u = b.transpose() * b;
    const Vector gb = b.transpose() * r;
    // The Gauss–Newton step would lower ‖r‖² by gbᵀU⁻¹gb: below the tolerance, no step is tried
    // (at rounding level a trial only fails, and λ climbs through a dozen more rollouts).
    if (gb.dot(small_factor(u).solve(gb)) <= tolerance * cost) break;
    Matrix ul = u;
    ul.diagonal() += lambda * marquardt_diagonal(u);
    const Vector trial = z - small_factor(ul).solve(gb);
    // A start state beyond the bound is a run along a direction the positions do not fix.
    Matrix trial_states;
    Vector r_try;
    double c_try = std::numeric_limits<double>::infinity();
    if (trial.cwiseAbs().maxCoeff() <= max_abs) {
      if (fused)
        rollout_with_start_jacobian(map, theta, trial, q, h, w, rw, inputs, trial_states, b_try);
      else
        trial_states = shooting_states(map, theta, trial, h, inputs);
      r_try = position_residuals(trial_states, q, w, rw);
      c_try = r_try.squaredNorm();
      if (fused && !b_try.allFinite()) c_try = std::numeric_limits<double>::infinity();
    }
    if (std::isfinite(c_try) && c_try < cost) {
      z = trial;
      states = std::move(trial_states);
      r = std::move(r_try);
      const bool done = cost - c_try <= tolerance * cost;
      lambda = std::max(lambda / 3.0, 1e-12);
      b_current = fused;
      if (fused) b.swap(b_try);
      cost = c_try;
      if (done) break;
    } else {
      lambda *= 4.0;
      if (lambda > 1e12 || cost <= rounding) break;
    }
  }
  return cost;
}

// p with P_q Φ̂_h(q0, p) = q1: Newton from p = 0 on the d equations, halving steps that do not
// lower the mismatch.
Vector one_step_momentum(const OneStepMap& map, ConstParams theta, const Vector& q0,
                         const Vector& q1, double h, const Matrix& u) {
  const Index d = q0.size();
  Vector z(2 * d);
  z << q0, Vector::Zero(d);
  Vector step(1);
  step(0) = h;
  const Vector u0 = u.rows() > 0 ? Vector(u.col(0)) : Vector();
  const auto mismatch = [&](const Vector& s) {
    if (u0.size() > 0)
      return Vector(map.forward_driven(theta, s, step, u0, nullptr).col(0).head(d) - q1);
    return Vector(map.apply(theta, s, step).col(0).head(d) - q1);
  };
  Vector f = mismatch(z);
  for (int it = 0; it < 30 && f.allFinite() && f.norm() > 0.0; ++it) {
    const Matrix jac =
        (u0.size() > 0 ? map.jacobian_driven(theta, z, h, u0) : map.jacobian(theta, z, h))
            .block(0, d, d, d);
    const Vector dp = dense::least_squares(jac, Vector(-f));
    if (!dp.allFinite()) break;
    double scale = 1.0;
    bool moved = false;
    for (int k = 0; k < 20; ++k, scale *= 0.5) {
      Vector trial = z;
      trial.tail(d) += scale * dp;
      const Vector ft = mismatch(trial);
      if (ft.allFinite() && ft.norm() < f.norm()) {
        z = trial;
        f = ft;
        moved = true;
        break;
      }
    }
    if (!moved) break;
  }
  return z.tail(d);
}

}  // namespace

double fit_start_states(const OneStepMap& map, ConstParams theta, const ShootingSegments& segs,
                        Matrix& z0, long iterations, bool several_starts, double max_abs,
                        double tolerance) {
  const Index d = segs.d;
  double sum = 0.0;
  for (Index s = 0; s < segs.size(); ++s) {
    throw_if_stop_requested("the fit of the hidden start states");
    const auto i = static_cast<std::size_t>(s);
    const Matrix& q = segs.q[i];
    const Vector& h = segs.h[i];
    const Vector& w = weights_of(segs, i);
    const Matrix& u = segs.inputs(s);
    const Vector given = z0.col(s);
    Vector best = given;
    const Vector& rw = segs.row_weight;
    double best_cost =
        fit_one_start(map, theta, q, h, w, rw, best, iterations, max_abs, u, tolerance);
    if (!several_starts) {
      z0.col(s) = best;
      sum += best_cost;
      continue;
    }
    // The given start, then p = 0 and the p that carries q[0] to q[1] in one step, each from
    // the first position (with the momenta observed, the first observed state): the lowest fit
    // is kept.
    const bool states = q.rows() == 2 * d;
    for (int k = 0; k < (states ? 1 : 2); ++k) {
      Vector z(2 * d);
      if (states) {
        z = q.col(0);
      } else {
        z.head(d) = q.col(0);
        z.tail(d) = k == 0 ? Vector(Vector::Zero(d))
                           : one_step_momentum(map, theta, q.col(0), q.col(1), h(0), u);
      }
      // The given start itself (a cut's first observed state): its fit, deterministic, is done.
      if (z == given) continue;
      const double c = fit_one_start(map, theta, q, h, w, rw, z, iterations, max_abs, u, tolerance);
      if (c < best_cost) {
        best_cost = c;
        best = z;
      }
    }
    z0.col(s) = best;
    sum += best_cost;
  }
  // Each segment's ‖r‖² was computed at its start state by its last rollout; only where one is
  // not finite (no finite rollout, or a start beyond max_abs) is the loss rolled out again.
  const Index n = segs.n_residuals();
  if (std::isfinite(sum)) return n > 0 ? sum / static_cast<double>(n) : 0.0;
  return shooting_loss(map, theta, z0, segs);
}

namespace {

// θ[b]'s Gauss–Newton standard error, √(loss · [A⁻¹]_bb / n), from `a`, the Cholesky factor of
// A = JᵀJ / n (n residuals; at the current λ, which only shrinks it).
double factored_standard_error(const Matrix& a, Index n_free, Index b, double loss, Index n) {
  Vector e = Vector::Zero(n_free);
  e(b) = 1.0;
  lapack::cholesky_solve(a.data(), n_free, e.data());
  return std::sqrt(std::max(0.0, loss * e(b) / static_cast<double>(n)));
}

// A trial of the joint step δ = (δθ, δz): θ moved by the reduced system's `step`, and each
// segment's start state by its own back-substitution, with the decrease the Gauss–Newton model
// predicts, ½ (λ δᵀDδ − gᵀδ) in the cost ½ scale² ‖r‖² (the loss is twice the cost).
struct JointTrial {
  Vector theta;
  Matrix z0;
  double predicted = 0.0;
};
JointTrial joint_trial(const Vector& theta, const Matrix& z0, const Vector& step,
                       const NormalEquations& ne, const std::vector<SegmentTerms>& terms,
                       Index n_free, double lambda) {
  JointTrial t{theta, z0, 0.0};
  t.theta.head(n_free) += step;
  double predicted =
      -ne.g.dot(step) + lambda * step.dot(marquardt_diagonal(ne.a).cwiseProduct(step));
  for (Index s = 0; s < z0.cols(); ++s) {
    const SegmentTerms& x = terms[static_cast<std::size_t>(s)];
    Matrix u = x.u;
    const Vector du = marquardt_diagonal(x.u);
    u.diagonal() += lambda * du;
    const Vector dz = -small_factor(u).solve(x.gb + x.w.transpose() * step);
    t.z0.col(s) += dz;
    predicted += -x.gb.dot(dz) + lambda * dz.dot(du.cwiseProduct(dz));
  }
  t.predicted = 0.5 * predicted;
  return t;
}

// After a failed trial (λ already raised): why the joint fit ends there, if it does. Damping
// past 1e10, or a loss at rounding level, where every trial fails alike.
std::optional<std::string> why_failed_trials_end(double lambda, double loss, double rounding) {
  if (lambda > 1e10) return "no step lowers the loss (damping above 1e10)";
  static_assert(kRoundingShare == 1e-20, "the message below names kRoundingShare");
  if (loss <= rounding)
    return "no step lowers the loss, which is at rounding level (below 1e-20 of the "
           "positions' mean square)";
  return std::nullopt;
}

// Three significant digits.
std::string fmt_short(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

// The fall of the cost (half the loss) that the local model predicts for the Gauss–Newton step
// from (θ, z0) (λ = 1e-12, Marquardt's scaling, as a floor for directions the data do not fix);
// infinity where the reduced system does not factor.
double gauss_newton_predicted(NormalEquations& ne, const std::vector<SegmentTerms>& terms,
                              const ShootingSegments& train, const Vector& theta, const Matrix& z0,
                              Index n_free) {
  constexpr double kGaussNewtonLambda = 1e-12;
  Matrix a;
  Vector g;
  reduce(ne, terms, train, kGaussNewtonLambda, a, g);
  Vector step = -g;
  if (!lapack::cholesky(a.data(), n_free)) return std::numeric_limits<double>::infinity();
  lapack::cholesky_solve(a.data(), n_free, step.data());
  if (!step.allFinite()) return std::numeric_limits<double>::infinity();
  return joint_trial(theta, z0, step, ne, terms, n_free, kGaussNewtonLambda).predicted;
}

// Why the fit ends before a trial, if the Gauss–Newton step's predicted fall of the loss says
// that no step from here can matter. In units of χ² (n · Δloss / loss) the fall that the model
// predicts for the step bounds every parameter's move in its own standard error: the step's
// component b satisfies δ_b² ≤ [A⁻¹]_bb · gᵀA⁻¹g (Cauchy–Schwarz in A⁻¹'s inner product), and
// gᵀA⁻¹g is at most the predicted fall, so |δ_b| ≤ SE_b · √(predicted χ² fall) for the watched
// parameter and every other. A predicted fall of at most converged_se² moves the watched parameter
// by at most converged_se of its standard error (what the rule of three accepted steps asks of
// each), one of at most converged_chi2 is a small step in χ²'s units; below 1e-10 of the loss
// itself the loss is at its rounding level, where every trial fails alike. Every step that LM could
// still take is then smaller.
std::optional<std::string> why_predicted_converged(double predicted, double loss, Index n,
                                                   const ShootingOptions& options, bool watching) {
  if (!(loss > 0.0) || !std::isfinite(predicted)) return std::nullopt;
  const double fall = 2.0 * predicted;  // the loss is twice the cost
  const double chi2 = static_cast<double>(n) * fall / loss;
  const double se2 = options.converged_se * options.converged_se;
  if (watching && chi2 <= se2)
    return "converged: the Gauss-Newton step from the fit is predicted to lower chi-square by " +
           fmt_short(chi2) + ", so it moves the damping parameter by at most " +
           fmt_short(std::sqrt(std::max(chi2, 0.0))) + " of its standard error (below " +
           fmt_short(options.converged_se) + ")";
  if (options.converged_chi2 > 0.0 && chi2 <= options.converged_chi2)
    return "converged: the Gauss-Newton step from the fit is predicted to lower chi-square by " +
           fmt_short(chi2) + " (below " + fmt_short(options.converged_chi2) + ")";
  if (fall <= 1e-10 * loss)
    return "converged: the Gauss-Newton step from the fit is predicted to lower the loss by " +
           fmt_short(fall / loss) + " of itself (below 1e-10: the loss's rounding level)";
  return std::nullopt;
}

// Why three small steps ended the fit.
std::string converged_message(double converged_chi2) {
  return converged_chi2 > 0.0
             ? "converged: the loss changes by less than " + std::to_string(converged_chi2) +
                   " of chi-square (or 1e-10 of itself) per step"
             : "converged: the loss changes by less than 1e-10 of itself per step";
}

// Every accepted iterate, for the choice at the end.
struct ShootingIterate {
  long iteration;
  Vector theta;
  Matrix z0, val_z0;
  double val;
};

// The latest iterate whose held-out loss is within one standard error of the lowest: a
// held-out loss at the noise floor changes by less than its own noise from step to step, and
// the more converged fit of the positions is then the better estimate. Without held-out
// segments, the latest.
const ShootingIterate& chosen_iterate(const std::vector<ShootingIterate>& kept, double best_val,
                                      double best_val_se, bool no_val) {
  const ShootingIterate* chosen = &kept.front();
  for (const ShootingIterate& x : kept)
    if (x.val <= best_val + best_val_se || no_val) chosen = &x;
  return *chosen;
}

}  // namespace

double rounding_loss(const ShootingSegments& segs) {
  double sum = 0.0;
  for (std::size_t s = 0; s < segs.q.size(); ++s) {
    const Matrix& q = segs.q[s];
    sum += position_residuals(Matrix::Zero(q.rows(), q.cols()), q, weights_of(segs, s),
                              segs.row_weight)
               .squaredNorm();
  }
  const Index n = segs.n_residuals();
  return n > 0 ? kRoundingShare * sum / static_cast<double>(n) : 0.0;
}

namespace {

// One run of the joint Levenberg–Marquardt fit: its data, its damping, its counters of small
// steps and the iterates it accepted. Each iteration is three steps: the damped step from the
// current normal equations (damped_step), the stop tests before its rollout
// (converged_before_trial), and the trial itself (try_step), which on success records the
// iterate (accept). `finish` then keeps the chosen iterate.
class JointFit {
 public:
  JointFit(const OneStepMap& map, const ShootingSegments& train, const ShootingSegments& val,
           const ShootingOptions& options)
      : map_(map),
        train_(train),
        val_(val),
        options_(options),
        n_free_(options.n_free < 0 ? map.n_params() : options.n_free),
        scale_(1.0 / std::sqrt(static_cast<double>(train.n_residuals()))),
        n_val_(static_cast<double>(std::max<Index>(1, val.n_residuals()))),
        rounding_(rounding_loss(train)) {}

  // Starts at (θ, z0): the training loss there, and its held-out loss as the first iterate.
  // False where the rollout from the start is not finite (a trial core far from the data has
  // no Jacobian).
  bool start(const Vector& theta, const Matrix& z0, Matrix& val_z0) {
    rep_.initial_loss = loss_ = shooting_loss(map_, theta, z0, train_);
    if (!std::isfinite(loss_)) {
      rep_.final_loss = rep_.val_loss = std::numeric_limits<double>::infinity();
      rep_.message = "the rollout from the start is not finite";
      return false;
    }
    theta_ = theta;
    z0_ = z0;
    kept_.push_back({0, theta_, z0_, val_z0, val_loss(theta_, val_z0)});
    best_val_ = kept_.back().val;
    rep_.message = "maximum number of iterations reached";
    return true;
  }

  // The iterations, until a rule ends them or the budget runs out.
  void iterate(Matrix& val_z0) {
    for (long it = 1; it <= options_.iterations; ++it) {
      if (!refresh()) {
        rep_.stopped = true;
        rep_.message = "stopped by the caller";
        return;
      }
      ++rep_.iterations;
      std::optional<Vector> step = damped_step();
      if (!step) continue;
      JointTrial trial = joint_trial(theta_, z0_, *step, ne_, terms_, n_free_, lambda_);
      if (const auto why = converged_before_trial(trial)) {
        rep_.watch_converged = watch_se_ > 0.0;
        rep_.message = *why;
        return;
      }
      if (const auto why = try_step(std::move(trial), *step, it, val_z0)) {
        rep_.message = *why;
        return;
      }
    }
  }

  const ShootingReport& report() const { return rep_; }

  // The chosen iterate into (θ, z0, val_z0), and the report.
  ShootingReport finish(Vector& theta, Matrix& z0, Matrix& val_z0) {
    // The standard error of a mean of n squared Gaussian residuals is the mean times √(2/n).
    const ShootingIterate& chosen =
        chosen_iterate(kept_, best_val_, standard_error(best_val_), val_.size() == 0);
    theta = chosen.theta;
    z0 = chosen.z0;
    val_z0 = chosen.val_z0;
    rep_.best_iteration = chosen.iteration;
    rep_.final_loss = shooting_loss(map_, theta, z0, train_);
    rep_.val_loss = chosen.val;
    return rep_;
  }

 private:
  bool stop() const { return options_.should_stop && options_.should_stop(); }

  // The held-out loss, compared at its standard error: its start states to kScoringTolerance.
  double val_loss(ConstParams theta, Matrix& val_z0) const {
    return val_.size() > 0 ? fit_start_states(map_, theta, val_, val_z0, 30, false,
                                              options_.max_abs_state, kScoringTolerance)
                           : 0.0;
  }
  double standard_error(double loss) const { return loss * std::sqrt(2.0 / n_val_); }

  // The normal equations at the current iterate, unless they are already there. False: stopped.
  bool refresh() {
    if (stop()) return false;
    if (fresh_) return true;
    ne_ = accumulate(
        map_, theta_, z0_, train_, n_free_, scale_, false, [this] { return stop(); }, terms_);
    if (ne_.stopped) return false;
    fresh_ = true;
    return true;
  }

  // θ's step from the reduced system at the current λ, and the watched parameter's standard
  // error from its factor (watch_se_). None, with λ raised, where the system does not factor
  // or the step is not finite or runs ten times the size of θ (along a direction the positions
  // do not fix).
  std::optional<Vector> damped_step() {
    Matrix a;
    Vector g;
    reduce(ne_, terms_, train_, lambda_, a, g);
    Vector step = -g;
    if (!lapack::cholesky(a.data(), n_free_)) {
      lambda_ *= 10.0;
      return std::nullopt;
    }
    lapack::cholesky_solve(a.data(), n_free_, step.data());
    const Index b = options_.watch_index;
    watch_se_ = b >= 0 && b < n_free_ && options_.converged_se > 0.0
                    ? factored_standard_error(a, n_free_, b, loss_, train_.n_residuals())
                    : 0.0;
    if (watch_se_ > 0.0) rep_.watch_se = watch_se_;
    if (!step.allFinite() || step.norm() > 10.0 * (1.0 + theta_.head(n_free_).norm())) {
      lambda_ *= 4.0;
      return std::nullopt;
    }
    return step;
  }

  // The damped step's predicted fall is at most Gauss–Newton's: only a small one is worth the
  // undamped step's (a reduction and a factorisation of n_free, no rollout).
  std::optional<std::string> converged_before_trial(const JointTrial& trial) {
    const bool watching = watch_se_ > 0.0;
    const Index n = train_.n_residuals();
    if (!why_predicted_converged(trial.predicted, loss_, n, options_, watching))
      return std::nullopt;
    const double fall = gauss_newton_predicted(ne_, terms_, train_, theta_, z0_, n_free_);
    return why_predicted_converged(fall, loss_, n, options_, watching);
  }

  // The trial's rollout; Nielsen's update of λ from the gain ratio ρ (actual over predicted
  // decrease; the loss is twice the cost). Returns why the fit ends, if it does.
  std::optional<std::string> try_step(JointTrial trial, const Vector& step, long it,
                                      Matrix& val_z0) {
    const double loss_try = trial.z0.cwiseAbs().maxCoeff() <= options_.max_abs_state
                                ? shooting_loss(map_, trial.theta, trial.z0, train_)
                                : std::numeric_limits<double>::infinity();
    const double rho = trial.predicted > 0.0 ? 0.5 * (loss_ - loss_try) / trial.predicted : -1.0;
    if (!(std::isfinite(loss_try) && loss_try < loss_)) {
      lambda_ *= nu_;
      nu_ *= 2.0;
      return why_failed_trials_end(lambda_, loss_, rounding_);
    }
    nu_ = 2.0;
    ++rep_.accepted;
    count_small_steps(step, loss_try);
    theta_ = std::move(trial.theta);
    z0_ = std::move(trial.z0);
    loss_ = loss_try;
    fresh_ = false;
    lambda_ = std::max(
        lambda_ * std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * std::min(rho, 1.0) - 1.0, 3)), 1e-10);
    return accept(it, val_z0);
  }

  // The counters of small steps in a row, for an accepted step to loss_try.
  void count_small_steps(const Vector& step, double loss_try) {
    const double n_train = static_cast<double>(train_.n_residuals());
    const bool small = (loss_ - loss_try) <= 1e-10 * loss_ ||
                       n_train * (loss_ - loss_try) <= options_.converged_chi2 * loss_try;
    // Counted only for a step near Gauss–Newton's (λ small) that lowers χ² by less than 1: a
    // heavily damped step is small in every direction, and a larger fall of χ² still moves θ.
    const bool watch_small =
        watch_se_ > 0.0 && lambda_ <= 1e-2 && n_train * (loss_ - loss_try) <= loss_try &&
        std::abs(step(options_.watch_index)) <= options_.converged_se * watch_se_;
    watch_steps_ = watch_small ? watch_steps_ + 1 : 0;
    small_steps_ = small ? small_steps_ + 1 : 0;
  }

  // The accepted iterate's held-out loss, kept; why the fit ends there, if it does.
  std::optional<std::string> accept(long it, Matrix& val_z0) {
    const double v = val_loss(theta_, val_z0);
    if (options_.on_accepted) options_.on_accepted(it, loss_, v);
    kept_.push_back({it, theta_, z0_, val_z0, v});
    // Patience counts steps whose held-out loss is above the lowest by more than its standard
    // error (below): at the noise floor the fit goes on converging.
    if (v < best_val_) best_val_ = v;
    if (v <= best_val_ + standard_error(best_val_)) {
      since_best_ = 0;
    } else if (++since_best_ >= options_.patience) {
      return "the held-out loss stayed more than its standard error above the lowest for " +
             std::to_string(options_.patience) + " steps";
    }
    if (watch_steps_ >= 3) {
      rep_.watch_converged = true;
      return "converged: three steps in a row each moved the damping parameter by less than " +
             std::to_string(options_.converged_se) + " of its standard error";
    }
    if (small_steps_ >= 3) return converged_message(options_.converged_chi2);
    return std::nullopt;
  }

  const OneStepMap& map_;
  const ShootingSegments& train_;
  const ShootingSegments& val_;
  const ShootingOptions& options_;
  const Index n_free_;
  const double scale_, n_val_, rounding_;
  Vector theta_;
  Matrix z0_;
  double loss_ = 0.0, best_val_ = 0.0, watch_se_ = 0.0;
  double lambda_ = 1e-4, nu_ = 2.0;
  long since_best_ = 0, small_steps_ = 0, watch_steps_ = 0;
  bool fresh_ = false;
  NormalEquations ne_;
  std::vector<SegmentTerms> terms_;
  std::vector<ShootingIterate> kept_;
  ShootingReport rep_;
};

}  // namespace

ShootingReport fit_shooting(const OneStepMap& map, Vector& theta, Matrix& z0,
                            const ShootingSegments& train, Matrix& val_z0,
                            const ShootingSegments& val, const ShootingOptions& options) {
  train.validate("shooting: training segments");
  if (val.size() > 0) val.validate("shooting: held-out segments");
  require(z0.rows() == 2 * train.d && z0.cols() == train.size(),
          "shooting: z0 must be 2d x segments");
  JointFit fit(map, train, val, options);
  if (!fit.start(theta, z0, val_z0)) return fit.report();
  fit.iterate(val_z0);
  return fit.finish(theta, z0, val_z0);
}

}  // namespace csympnet

namespace csympnet {

Vector state_from_positions(const OneStepMap& map, ConstParams theta, const Matrix& q,
                            const Vector& t, double* rms, const Matrix& u, Matrix* residuals) {
  const Index d = q.rows(), len = q.cols();
  require(2 * d == map.dim(), [&] {
    return "positions: " + std::to_string(d) +
           " per sample; the model has d = " + std::to_string(map.dim() / 2);
  });
  require(len >= 2 && t.size() == len,
          "positions: expected at least 2 samples, with one time each");
  ShootingSegments segs;
  segs.d = d;
  segs.q = {q};
  segs.h = {t.tail(len - 1) - t.head(len - 1)};
  segs.block = {0};
  if (u.rows() > 0) segs.u = {u};
  segs.validate("positions");
  Matrix best(2 * d, 1);
  best.col(0).head(d) = q.col(0);
  best.col(0).tail(d).setZero();
  const double best_loss = fit_start_states(map, theta, segs, best, 100, true);
  require(std::isfinite(best_loss), "positions: no start state gives a finite rollout");
  if (rms != nullptr) *rms = std::sqrt(best_loss);
  const Matrix states = shooting_states(map, theta, best.col(0), segs.h[0], u);
  if (residuals != nullptr) *residuals = states.topRows(d) - q;
  return states.col(len - 1);
}

}  // namespace csympnet
