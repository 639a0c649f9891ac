// The window sums of the identification over chunks, threads and MPI ranks, with the same
// bits for any number of them: the loss (AdamW, validation) and the normal equations (LM, the
// interval). Private to the library (src/identify).
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "csympnet/core/communicator.hpp"
#include "csympnet/core/thread_team.hpp"
#include "csympnet/train/chunk_tree.hpp"
#include "csympnet/train/window_loss.hpp"

namespace csympnet::detail {

std::vector<Index> index_range(Index begin, Index end);

// The window loss (and gradient) of a map on windows w, as chunks of windows summed over the
// fixed tree of chunk_tree.hpp, each rank computing its share of the chunks and its threads
// splitting that share: the same bits for any number of ranks and threads. Up to
// kWindowLossOneChunkMaxWindows windows it is one chunk, window_loss() itself, on every rank,
// so fits of that size keep the bits of earlier versions; above, chunks of kDefaultChunkPairs.
inline constexpr Index kWindowLossOneChunkMaxWindows = 4096;

class ChunkedWindowLoss {
 public:
  ChunkedWindowLoss(const OneStepMap& map, const WindowSet& w, bool balanced,
                    const Communicator& comm, int threads);
  double operator()(ConstParams theta, Vector* grad);

 private:
  const OneStepMap* map_;
  const Communicator* comm_;
  bool balanced_;
  ChunkPlan plan_;
  Index first_ = 0;
  std::vector<WindowSet> chunks_;  // this rank's, from chunk first_ on
  std::shared_ptr<ThreadTeam> team_;
  std::vector<std::vector<ForwardCache>> caches_;
  std::vector<Vector> grads_;
};

// window_normal_equations() over the ranks with the same bits for any number of them: up to
// kLmOneChunkMaxWindows windows the routine itself on every rank; above, chunks of
// kLmChunkWindows windows, each the routine on its windows, summed over the fixed tree of
// chunk_tree.hpp, each rank computing its share. `should_stop` must give every rank the same
// answer (a collective agreement): it is polled per chunk of the routine in the first case;
// in the second per chunk of 1,024 windows in one process, but once before the chunks over
// several ranks, which own different numbers of chunks and cannot agree in between.
inline constexpr Index kLmOneChunkMaxWindows = 4096;
inline constexpr Index kLmChunkWindows = 1024;
NormalEquations normal_equations_over_ranks(const OneStepMap& map, ConstParams theta,
                                            const WindowSet& w, bool balanced, double scale,
                                            bool with_scores,
                                            const std::function<bool()>& should_stop,
                                            const Communicator& comm);

}  // namespace csympnet::detail
