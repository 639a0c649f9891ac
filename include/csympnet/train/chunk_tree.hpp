// Sums over chunks of the training pairs that give the same bits however the chunks are
// shared out among threads and MPI ranks (docs/architecture.md, "Chunks and one reduction
// tree").
//
// The pairs are cut into M chunks of C consecutive columns (ChunkPlan; C depends on the
// problem only). A chunk's value (its part of the loss and of the gradient) is summed with the
// others over one fixed binary tree on chunk indices: node [a, a + 2^k), a a multiple of 2^k,
// is the sum of its two halves, left + right; a half that starts at or past M is missing and
// the node is its left half. Any contiguous range of chunks is a union of aligned nodes, so a
// worker owning a range sums its chunks into those nodes (TreeSum, a stack, as in pairwise
// summation) and the nodes of all workers, in order, finish the same tree. Floating-point
// addition is commutative, so every node holds the same bits whoever computed it.
#pragma once

#include <functional>
#include <vector>

#include "csympnet/core/communicator.hpp"
#include "csympnet/core/thread_team.hpp"
#include "csympnet/core/types.hpp"

namespace csympnet {

// Pair counts up to this run as one chunk by default: the whole batch, as one forward and
// backward pass (and its column-split threads). Every paper preset and reproduction suite
// (at most 400 training pairs) stays below it and keeps its bits; above it, chunks pay (the
// product kernels cover the parameter gradients' sums over ≤ 256 columns, Eigen's generic
// path runs beyond about 450: docs/benchmarks.md, "Chunk size").
inline constexpr Index kOneChunkMaxPairs = 512;
// The chunk above that: fastest per pair at d = 100 on one thread (docs/benchmarks.md).
inline constexpr Index kDefaultChunkPairs = 256;

// How n pairs are cut: chunks [i·C, min((i+1)·C, n)).
struct ChunkPlan {
  Index pairs = 0;
  Index chunk_pairs = 0;  // C
  Index chunks() const { return pairs == 0 ? 0 : (pairs + chunk_pairs - 1) / chunk_pairs; }
  Index begin(Index chunk) const { return chunk * chunk_pairs; }
  Index end(Index chunk) const { return std::min(pairs, (chunk + 1) * chunk_pairs); }
};

// The plan for n pairs: chunks of `requested` pairs when it is > 0, else one chunk up to
// kOneChunkMaxPairs pairs and chunks of kDefaultChunkPairs above.
ChunkPlan plan_chunks(Index n, Index requested = 0);

// Contiguous share `part` of `parts` of [begin, end): [begin + ⌊part·m/parts⌋, ...).
std::pair<Index, Index> share_of(Index begin, Index end, int part, int parts);

// One node of the tree: chunks [start, start + size), size a power of two, start a multiple
// of it, and their sum.
struct TreeNode {
  Index start = 0;
  Index size = 0;
  Vector sum;
};

// The nodes of a contiguous range of chunks, fed in order: push() merges the top two nodes
// while they are the two halves of one node, so it holds the range's largest aligned nodes,
// O(log M) of them.
class TreeSum {
 public:
  // Appends node [start, start + size), which must begin where the last one ended.
  void push(Index start, Index size, Vector sum);
  const std::vector<TreeNode>& nodes() const { return nodes_; }
  std::vector<TreeNode> take() { return std::move(nodes_); }
  // The root's sum, when the nodes pushed cover chunks [0, M): the remaining nodes (of
  // decreasing size) fold from the right, each node's missing right halves passed through.
  Vector total() const;

 private:
  std::vector<TreeNode> nodes_;
};

// Nodes as one message: per node start, size, then its values (all of `width`).
std::vector<double> pack_nodes(const std::vector<TreeNode>& nodes, Index width);
std::vector<TreeNode> unpack_nodes(const std::vector<double>& message, Index width);

// The tree sum over `chunks` chunks of values of length `width`: this rank's share of the
// chunks (share_of over comm's ranks), split again over the team's threads (null: one), each
// chunk's value written by value(chunk, part, out) (part: the thread's share, for per-thread
// scratch; out has length width and is overwritten); the nodes of every rank are all-gathered
// and finished in order. Same bits for any team and any number of ranks. `bytes_sent`, when
// not null, receives the bytes this rank sent.
Vector tree_sum(Index chunks, Index width,
                const std::function<void(Index chunk, int part, Vector& out)>& value,
                ThreadTeam* team, const Communicator& comm, std::size_t* bytes_sent = nullptr);

}  // namespace csympnet
