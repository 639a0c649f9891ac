#include "csympnet/train/chunk_tree.hpp"

#include <algorithm>

#include "csympnet/core/error.hpp"

namespace csympnet {

ChunkPlan plan_chunks(Index n, Index requested) {
  require(n >= 0 && requested >= 0, "plan_chunks: negative count");
  ChunkPlan p;
  p.pairs = n;
  if (requested > 0)
    p.chunk_pairs = std::min(requested, std::max<Index>(n, 1));
  else
    p.chunk_pairs = n <= kOneChunkMaxPairs ? std::max<Index>(n, 1) : kDefaultChunkPairs;
  return p;
}

std::pair<Index, Index> share_of(Index begin, Index end, int part, int parts) {
  const Index m = end - begin;
  return {begin + m * part / parts, begin + m * (part + 1) / parts};
}

void TreeSum::push(Index start, Index size, Vector sum) {
  require(size > 0 && (size & (size - 1)) == 0 && start % size == 0,
          "TreeSum: a node must be aligned to its power-of-two size");
  require(nodes_.empty() || nodes_.back().start + nodes_.back().size == start,
          "TreeSum: nodes must be pushed in order, without gaps");
  nodes_.push_back({start, size, std::move(sum)});
  // Two halves of one node: left + right (commutative, so `left += right` has the same bits).
  while (nodes_.size() >= 2) {
    TreeNode& left = nodes_[nodes_.size() - 2];
    const TreeNode& right = nodes_.back();
    if (left.size != right.size || left.start % (2 * left.size) != 0) break;
    left.sum += right.sum;
    left.size *= 2;
    nodes_.pop_back();
  }
}

Vector TreeSum::total() const {
  require(!nodes_.empty() && nodes_.front().start == 0, "TreeSum: no nodes from chunk 0");
  // Past the first node the sizes decrease: each remaining node is the left half of the node
  // that holds it and all nodes to its right, so the sum folds from the right.
  Vector acc = nodes_.back().sum;
  for (std::size_t i = nodes_.size() - 1; i-- > 0;) acc = nodes_[i].sum + acc;
  return acc;
}

std::vector<double> pack_nodes(const std::vector<TreeNode>& nodes, Index width) {
  std::vector<double> m;
  m.reserve(nodes.size() * static_cast<std::size_t>(width + 2));
  for (const TreeNode& n : nodes) {
    require(n.sum.size() == width, "pack_nodes: a node of the wrong width");
    m.push_back(static_cast<double>(n.start));
    m.push_back(static_cast<double>(n.size));
    m.insert(m.end(), n.sum.data(), n.sum.data() + width);
  }
  return m;
}

std::vector<TreeNode> unpack_nodes(const std::vector<double>& message, Index width) {
  const std::size_t stride = static_cast<std::size_t>(width + 2);
  require(message.size() % stride == 0, "unpack_nodes: a message of the wrong length");
  std::vector<TreeNode> nodes;
  for (std::size_t i = 0; i < message.size(); i += stride) {
    TreeNode n;
    n.start = static_cast<Index>(message[i]);
    n.size = static_cast<Index>(message[i + 1]);
    n.sum = Eigen::Map<const Vector>(message.data() + i + 2, width);
    nodes.push_back(std::move(n));
  }
  return nodes;
}

Vector tree_sum(Index chunks, Index width,
                const std::function<void(Index chunk, int part, Vector& out)>& value,
                ThreadTeam* team, const Communicator& comm, std::size_t* bytes_sent) {
  require(chunks >= 1 && width >= 1, "tree_sum: need at least one chunk and one value");
  // Not a structured binding: the lambda below captures these, which clang 14 cannot.
  const auto share = share_of(0, chunks, comm.rank(), comm.size());
  const auto first = share.first, last = share.second;
  const int parts = team != nullptr ? team->size() : 1;
  std::vector<TreeSum> sums(static_cast<std::size_t>(parts));
  const auto run_part = [&](int part) {
    const auto [b, e] = share_of(first, last, part, parts);
    TreeSum& s = sums[static_cast<std::size_t>(part)];
    for (Index c = b; c < e; ++c) {
      Vector v(width);
      value(c, part, v);
      s.push(c, 1, std::move(v));
    }
  };
  if (team != nullptr && parts > 1)
    team->run(run_part);
  else
    run_part(0);
  // The threads' nodes, in order, into this rank's largest aligned nodes.
  TreeSum mine;
  for (TreeSum& s : sums)
    for (TreeNode& n : s.take()) mine.push(n.start, n.size, std::move(n.sum));
  TreeSum all;
  if (comm.size() == 1) {
    all = std::move(mine);
  } else {
    const std::vector<double> message = pack_nodes(mine.nodes(), width);
    if (bytes_sent != nullptr) *bytes_sent = message.size() * sizeof(double);
    for (TreeNode& n : unpack_nodes(comm.all_gather(message), width))
      all.push(n.start, n.size, std::move(n.sum));
  }
  require(!all.nodes().empty() && all.nodes().back().start + all.nodes().back().size == chunks,
          "tree_sum: the ranks' chunks do not cover the plan");
  return all.total();
}

}  // namespace csympnet
