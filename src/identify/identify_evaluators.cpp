#include "identify_evaluators.hpp"

#include <algorithm>
#include <numeric>

namespace csympnet::detail {

std::vector<Index> index_range(Index begin, Index end) {
  std::vector<Index> idx(static_cast<std::size_t>(end - begin));
  std::iota(idx.begin(), idx.end(), begin);
  return idx;
}

namespace {
ChunkPlan plan_window_chunks(Index windows) {
  return plan_chunks(windows, windows <= kWindowLossOneChunkMaxWindows ? std::max<Index>(windows, 1)
                                                                       : kDefaultChunkPairs);
}
}  // namespace

ChunkedWindowLoss::ChunkedWindowLoss(const OneStepMap& map, const WindowSet& w, bool balanced,
                                     const Communicator& comm, int threads)
    : map_(&map), comm_(&comm), balanced_(balanced), plan_(plan_window_chunks(w.size())) {
  if (plan_.chunks() <= 1) {
    chunks_.push_back(w);
  } else {
    const auto [first, last] = share_of(0, plan_.chunks(), comm.rank(), comm.size());
    first_ = first;
    for (Index c = first; c < last; ++c)
      chunks_.push_back(select_windows(w, index_range(plan_.begin(c), plan_.end(c))));
    if (threads > 1) team_ = std::make_shared<ThreadTeam>(threads);
  }
  caches_.resize(static_cast<std::size_t>(std::max(1, threads)));
  grads_.resize(caches_.size());
}

double ChunkedWindowLoss::operator()(ConstParams theta, Vector* grad) {
  if (plan_.chunks() <= 1)
    return window_loss(*map_, theta, chunks_.front(), balanced_, grad,
                       grad != nullptr ? &caches_.front() : nullptr);
  const Index p = map_->n_params();
  const Index width = grad != nullptr ? p + 1 : 1;  // [gradient, loss]
  const auto value = [&](Index c, int part, Vector& out) {
    const auto t = static_cast<std::size_t>(part);
    Vector* g = grad != nullptr ? &grads_[t] : nullptr;
    const double l =
        window_loss_part(*map_, theta, chunks_.at(static_cast<std::size_t>(c - first_)), balanced_,
                         plan_.pairs, g, &caches_[t]);
    if (g != nullptr) out.head(p) = *g;
    out(width - 1) = l;
  };
  const Vector total = tree_sum(plan_.chunks(), width, value, team_.get(), *comm_);
  if (grad != nullptr) *grad = total.head(p);
  return total(width - 1);
}

NormalEquations normal_equations_over_ranks(const OneStepMap& map, ConstParams theta,
                                            const WindowSet& w, bool balanced, double scale,
                                            bool with_scores,
                                            const std::function<bool()>& should_stop,
                                            const Communicator& comm) {
  if (w.size() <= kLmOneChunkMaxWindows)
    return window_normal_equations(map, theta, w, balanced, scale, with_scores, should_stop);
  const Index p = map.n_params();
  NormalEquations ne;
  ne.a.setZero(p, p);  // sized, as the routine's are, even when stopped
  ne.g.setZero(p);
  const bool poll_each = comm.size() == 1 && should_stop;
  if (!poll_each && should_stop && should_stop()) {
    ne.stopped = true;
    return ne;
  }
  Index blocks = 0;
  if (with_scores)
    for (Index b : w.block) blocks = std::max(blocks, b + 1);
  const ChunkPlan plan = plan_chunks(w.size(), kLmChunkWindows);
  const Index lower = p * (p + 1) / 2;             // A's lower triangle, column by column
  const Index width = lower + p + 1 + p * blocks;  // [A, g, cost, scores]
  const auto value = [&](Index c, int /*part*/, Vector& out) {
    // One process, chunks in order: once stopped, the rest are skipped and never polled.
    if (poll_each && !ne.stopped && should_stop()) ne.stopped = true;
    if (ne.stopped) {
      out.setZero();
      return;
    }
    const WindowSet part = select_windows(w, index_range(plan.begin(c), plan.end(c)));
    const NormalEquations one =
        window_normal_equations(map, theta, part, balanced, scale, with_scores);
    out.setZero();
    for (Index j = 0, at = 0; j < p; at += p - j, ++j)
      out.segment(at, p - j) = one.a.col(j).tail(p - j);
    out.segment(lower, p) = one.g;
    out(lower + p) = one.cost;
    if (with_scores)  // the chunk's blocks are numbered as the whole set's, from 0 on
      out.segment(lower + p + 1, one.scores.size()) =
          Eigen::Map<const Vector>(one.scores.data(), one.scores.size());
  };
  const Vector total = tree_sum(plan.chunks(), width, value, nullptr, comm);
  if (ne.stopped) return ne;  // incomplete sums: not to be used
  for (Index j = 0, at = 0; j < p; at += p - j, ++j)
    ne.a.col(j).tail(p - j) = total.segment(at, p - j);
  ne.g = total.segment(lower, p);
  ne.cost = total(lower + p);
  if (with_scores) ne.scores = Eigen::Map<const Matrix>(total.data() + lower + p + 1, p, blocks);
  return ne;
}

}  // namespace csympnet::detail
