// The one-step loss of a map over pairs cut into chunks (chunk_tree.hpp): each chunk runs the
// serial forward and backward pass, the chunks' parts of the loss and gradient are summed over
// the fixed tree, on this process's threads and the communicator's ranks. The bits depend on
// the chunk plan alone. A plan of one chunk is one_step_loss() itself (and its column-split
// threads), on every rank.
#pragma once

#include <map>
#include <memory>
#include <vector>

#include "csympnet/core/communicator.hpp"
#include "csympnet/core/thread_team.hpp"
#include "csympnet/data/dataset.hpp"
#include "csympnet/models/one_step_map.hpp"
#include "csympnet/train/chunk_tree.hpp"
#include "csympnet/train/loss.hpp"

namespace csympnet {

class ChunkedOneStepLoss {
 public:
  // The loss of `map` (which must outlive this) on `pairs`, cut by plan_chunks(pairs.size(),
  // chunk_pairs). Keeps a copy of this rank's chunks of the pairs only, or of all of them when
  // `batches` (for batch_loss()). threads: the team's size for this rank's chunks.
  ChunkedOneStepLoss(const OneStepMap& map, const PairSet& pairs, Index chunk_pairs, int threads,
                     const Communicator& comm, bool batches = false);

  // The loss on all pairs; grad (when not null) overwritten with its gradient.
  double loss(ConstParams theta, Vector* grad);
  // The loss (mean over the batch) on the pairs numbered `batch`, with its own chunk plan;
  // needs `batches` at construction.
  double batch_loss(ConstParams theta, const std::vector<Index>& batch, Vector* grad);

  const ChunkPlan& plan() const { return plan_; }
  // Bytes this rank sent in the last all-gather of nodes (0 on one rank).
  std::size_t last_bytes_sent() const { return bytes_sent_; }

 private:
  double one_chunk(ConstParams theta, const PairSet& pairs, Vector* grad);
  double chunked(ConstParams theta, const ChunkPlan& plan, Vector* grad,
                 const std::function<PairSet(Index chunk)>& select,
                 const std::function<const PairSet&(Index chunk)>& held);

  const OneStepMap* map_;
  const Communicator* comm_;
  bool batches_;
  Index requested_chunk_pairs_;
  ChunkPlan plan_;
  Index first_chunk_ = 0;        // this rank's first chunk (plan_)
  std::vector<PairSet> chunks_;  // this rank's chunks of the pairs
  PairSet all_;                  // every pair, when built for batches
  std::shared_ptr<ThreadTeam> team_;
  std::vector<ForwardCache> caches_;   // one per thread
  std::vector<Vector> grads_;          // one per thread
  std::map<Index, LossSplit> splits_;  // one chunk: the column split per batch size
  std::size_t bytes_sent_ = 0;
};

}  // namespace csympnet
