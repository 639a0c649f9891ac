#include "csympnet/train/chunked_loss.hpp"

#include <numeric>

#include "csympnet/core/error.hpp"

namespace csympnet {

namespace {

std::vector<Index> index_range(Index begin, Index end) {
  std::vector<Index> idx(static_cast<std::size_t>(end - begin));
  std::iota(idx.begin(), idx.end(), begin);
  return idx;
}

}  // namespace

ChunkedOneStepLoss::ChunkedOneStepLoss(const OneStepMap& map, const PairSet& pairs,
                                       Index chunk_pairs, int threads, const Communicator& comm,
                                       bool batches)
    : map_(&map),
      comm_(&comm),
      batches_(batches),
      requested_chunk_pairs_(chunk_pairs),
      plan_(plan_chunks(pairs.size(), chunk_pairs)) {
  require(threads >= 1 && threads <= ThreadTeam::kMaxThreads, "chunked loss: bad thread count");
  if (batches) {
    all_ = pairs;
  } else if (plan_.chunks() <= 1) {
    chunks_.push_back(pairs);
  } else {
    const auto [first, last] = share_of(0, plan_.chunks(), comm.rank(), comm.size());
    first_chunk_ = first;
    for (Index c = first; c < last; ++c)
      chunks_.push_back(select_pairs(pairs, index_range(plan_.begin(c), plan_.end(c))));
  }
  if (threads > 1) team_ = std::make_shared<ThreadTeam>(threads);
  if (team_ && !batches && plan_.chunks() <= 1) {
    // One chunk: the team serves only the column split; without one, no idle workers.
    const LossSplit& split =
        splits_.emplace(pairs.size(), plan_loss_split(map, pairs.size(), team_.get()))
            .first->second;
    if (!split.active()) team_.reset();
  }
  caches_.resize(static_cast<std::size_t>(threads));
  grads_.resize(static_cast<std::size_t>(threads));
}

double ChunkedOneStepLoss::one_chunk(ConstParams theta, const PairSet& pairs, Vector* grad) {
  // Every rank computes it whole: one_step_loss() with the column split its size allows, or
  // for a value alone the plain serial pass.
  if (grad == nullptr) return one_step_loss(*map_, theta, pairs);
  auto it = splits_.find(pairs.size());
  if (it == splits_.end())
    it = splits_.emplace(pairs.size(), plan_loss_split(*map_, pairs.size(), team_.get())).first;
  return one_step_loss(*map_, theta, pairs, grad, &caches_[0], it->second);
}

double ChunkedOneStepLoss::chunked(ConstParams theta, const ChunkPlan& plan, Vector* grad,
                                   const std::function<PairSet(Index chunk)>& select,
                                   const std::function<const PairSet&(Index chunk)>& held) {
  const Index p = map_->n_params();
  const bool with_grad = grad != nullptr;
  const Index width = with_grad ? p + 1 : 1;  // [gradient, loss]
  const auto value = [&](Index c, int part, Vector& out) {
    const std::size_t t = static_cast<std::size_t>(part);
    PairSet own;
    const PairSet& pairs = held ? held(c) : (own = select(c));
    Vector* g = with_grad ? &grads_[t] : nullptr;
    const double l = one_step_loss_part(*map_, theta, pairs, plan.pairs, g, &caches_[t]);
    if (with_grad) out.head(p) = *g;
    out(width - 1) = l;
  };
  const Vector total = tree_sum(plan.chunks(), width, value, team_.get(), *comm_, &bytes_sent_);
  if (with_grad) *grad = total.head(p);
  return total(width - 1);
}

double ChunkedOneStepLoss::loss(ConstParams theta, Vector* grad) {
  if (plan_.chunks() <= 1) return one_chunk(theta, batches_ ? all_ : chunks_.at(0), grad);
  if (batches_)
    return chunked(
        theta, plan_, grad,
        [this](Index c) { return select_pairs(all_, index_range(plan_.begin(c), plan_.end(c))); },
        {});
  return chunked(theta, plan_, grad, {}, [this](Index c) -> const PairSet& {
    return chunks_.at(static_cast<std::size_t>(c - first_chunk_));
  });
}

double ChunkedOneStepLoss::batch_loss(ConstParams theta, const std::vector<Index>& batch,
                                      Vector* grad) {
  require(batches_, "chunked loss: built without the pairs for batches");
  require(!batch.empty(), "chunked loss: an empty batch");
  const ChunkPlan plan = plan_chunks(static_cast<Index>(batch.size()), requested_chunk_pairs_);
  if (plan.chunks() <= 1) return one_chunk(theta, select_pairs(all_, batch), grad);
  return chunked(theta, plan, grad,
                 [&](Index c) {
                   const auto b = batch.begin() + plan.begin(c);
                   return select_pairs(all_, std::vector<Index>(b, batch.begin() + plan.end(c)));
                 },
                 {});
}

}  // namespace csympnet
