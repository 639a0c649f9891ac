// The chunk tree (chunk_tree.hpp): sums over chunks that give the same bits whatever the
// contiguous partition of the chunks over workers (threads, ranks), equal to one recursive
// pairwise sum; and the chunked one-step loss and mini-batch training built on it.
#include <gtest/gtest.h>

#include <barrier>
#include <memory>
#include <random>
#include <thread>

#include "../src/models/csympnet_id.hpp"
#include "../src/models/la_sympnet.hpp"
#include "csympnet/core/error.hpp"
#include "csympnet/train/chunked_loss.hpp"
#include "csympnet/train/objective.hpp"
#include "csympnet/train/trainer.hpp"
#include "support/model_fixtures.hpp"
#include "support/random_data.hpp"
#include "support/same_bits.hpp"

namespace csympnet::testing {
namespace {

// The tree's definition, recursively: node [a, a + size) ∩ [0, m).
Vector reference_sum(const std::vector<Vector>& v, Index a, Index size) {
  const Index m = static_cast<Index>(v.size());
  if (size == 1) return v[static_cast<std::size_t>(a)];
  const Index half = size / 2;
  if (a + half >= m) return reference_sum(v, a, half);  // no right half
  return reference_sum(v, a, half) + reference_sum(v, a + half, half);
}

Vector reference_sum(const std::vector<Vector>& v) {
  Index size = 1;
  while (size < static_cast<Index>(v.size())) size *= 2;
  return reference_sum(v, 0, size);
}

// Values of wildly different magnitudes, so that another order of the sums changes bits.
std::vector<Vector> random_chunks(Index m, Index width, std::mt19937_64& gen) {
  std::normal_distribution<double> normal;
  std::uniform_int_distribution<int> exponent(-20, 20);
  std::vector<Vector> v(static_cast<std::size_t>(m), Vector(width));
  for (Vector& x : v)
    for (Index i = 0; i < width; ++i) x(i) = std::ldexp(normal(gen), exponent(gen));
  return v;
}

TEST(ChunkTree, AnyContiguousPartitionGivesTheReferenceSumToTheBit) {
  std::mt19937_64 gen(5);
  int order_matters = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const Index m = std::uniform_int_distribution<Index>(1, 70)(gen);
    const std::vector<Vector> v = random_chunks(m, 4, gen);
    const Vector reference = reference_sum(v);
    Vector left_to_right = Vector::Zero(4);
    for (const Vector& x : v) left_to_right += x;
    order_matters += same_bits(reference, left_to_right) ? 0 : 1;
    // A random contiguous partition into workers (some empty), each with its own stack; their
    // nodes, in order, finish the tree.
    const int workers = std::uniform_int_distribution<int>(1, 9)(gen);
    std::vector<Index> cuts = {0, m};
    for (int w = 1; w < workers; ++w)
      cuts.push_back(std::uniform_int_distribution<Index>(0, m)(gen));
    std::sort(cuts.begin(), cuts.end());
    TreeSum all;
    std::size_t most_nodes = 0;
    for (std::size_t w = 0; w + 1 < cuts.size(); ++w) {
      TreeSum mine;
      for (Index c = cuts[w]; c < cuts[w + 1]; ++c) mine.push(c, 1, v[static_cast<std::size_t>(c)]);
      most_nodes = std::max(most_nodes, mine.nodes().size());
      for (TreeNode& n : mine.take()) all.push(n.start, n.size, std::move(n.sum));
    }
    // A worker's stack stays logarithmic: at most two nodes per level.
    EXPECT_LE(most_nodes, 2 * static_cast<std::size_t>(std::log2(static_cast<double>(m)) + 1));
    EXPECT_TRUE(same_bits(all.total(), reference)) << "m = " << m << ", workers = " << workers;
  }
  EXPECT_GT(order_matters, 100);  // else bit equality would prove nothing about the order
}

TEST(ChunkTree, RefusesNodesOutOfOrderOrMisaligned) {
  TreeSum s;
  EXPECT_THROW(s.push(1, 2, Vector::Zero(1)), Error);  // start not a multiple of the size
  EXPECT_THROW(s.push(0, 3, Vector::Zero(1)), Error);  // size not a power of two
  s.push(0, 1, Vector::Zero(1));
  EXPECT_THROW(s.push(2, 1, Vector::Zero(1)), Error);  // a gap
  EXPECT_THROW(TreeSum().total(), Error);
}

TEST(ChunkTree, PlanKeepsSmallSetsWholeAndCutsLargeOnes) {
  EXPECT_EQ(plan_chunks(400).chunks(), 1);
  EXPECT_EQ(plan_chunks(kOneChunkMaxPairs).chunks(), 1);
  const ChunkPlan p = plan_chunks(kOneChunkMaxPairs + 1);
  EXPECT_EQ(p.chunk_pairs, kDefaultChunkPairs);
  EXPECT_EQ(p.end(p.chunks() - 1), kOneChunkMaxPairs + 1);
  EXPECT_EQ(plan_chunks(1000, 300).chunks(), 4);
  EXPECT_EQ(plan_chunks(1000, 300).end(3), 1000);
  EXPECT_EQ(plan_chunks(10, 300).chunks(), 1);
}

// K ranks as K threads of this process: all_gather through shared slots and a barrier.
class InProcessRanks {
 public:
  explicit InProcessRanks(int size) : slots_(static_cast<std::size_t>(size)), barrier_(size) {}
  class Rank final : public Communicator {
   public:
    Rank(InProcessRanks& all, int rank) : all_(all), rank_(rank) {}
    int rank() const override { return rank_; }
    int size() const override { return static_cast<int>(all_.slots_.size()); }
    std::vector<double> all_gather(const std::vector<double>& mine) const override {
      all_.slots_[static_cast<std::size_t>(rank_)] = mine;
      all_.barrier_.arrive_and_wait();
      std::vector<double> out;
      for (const auto& s : all_.slots_) out.insert(out.end(), s.begin(), s.end());
      all_.barrier_.arrive_and_wait();
      return out;
    }
    bool any(bool flag) const override {
      std::vector<double> all = all_gather({flag ? 1.0 : 0.0});
      return std::find(all.begin(), all.end(), 1.0) != all.end();
    }
    void abort(int) const override { std::abort(); }

   private:
    InProcessRanks& all_;
    int rank_;
  };

 private:
  std::vector<std::vector<double>> slots_;
  std::barrier<> barrier_;
};

// Runs job(comm) on `ranks` in-process ranks and returns rank 0's result.
template <class Job>
auto on_ranks(int ranks, const Job& job) {
  InProcessRanks all(ranks);
  std::vector<decltype(job(std::declval<const Communicator&>()))> out(
      static_cast<std::size_t>(ranks));
  std::vector<std::thread> threads;
  for (int r = 0; r < ranks; ++r)
    threads.emplace_back([&, r] {
      const InProcessRanks::Rank comm(all, r);
      out[static_cast<std::size_t>(r)] = job(comm);
    });
  for (std::thread& t : threads) t.join();
  for (int r = 1; r < ranks; ++r) EXPECT_TRUE(same_bits(out[0], out[static_cast<std::size_t>(r)]));
  return out[0];
}

TEST(ChunkTree, TreeSumOverThreadsAndRanksGivesTheReference) {
  std::mt19937_64 gen(8);
  for (Index m : {1, 2, 7, 33}) {
    const std::vector<Vector> v = random_chunks(m, 3, gen);
    const Vector reference = reference_sum(v);
    const auto value = [&v](Index c, int, Vector& out) { out = v[static_cast<std::size_t>(c)]; };
    for (int ranks : {1, 2, 3})
      for (int threads : {1, 2, 3}) {
        SCOPED_TRACE("m = " + std::to_string(m) + ", " + std::to_string(ranks) + " ranks × " +
                     std::to_string(threads) + " threads");
        const Vector got = on_ranks(ranks, [&](const Communicator& comm) {
          ThreadTeam team(threads);
          return tree_sum(m, 3, value, &team, comm);
        });
        EXPECT_TRUE(same_bits(got, reference));
      }
  }
}

struct Problem {
  std::unique_ptr<CSympNetId> map =
      std::make_unique<CSympNetId>(std::make_unique<LaSympNet>(3, 2, 3));
  PairSet pairs;
  Vector theta;
  explicit Problem(Index n) {
    std::mt19937_64 gen(11);
    pairs = random_pairs(map->dim(), n, gen);
    Rng rng(2, "init");
    theta = random_theta(*map, rng, 0.3);
  }
};

TEST(ChunkedLoss, OneChunkIsTheWholeLossAndChunksAgreeAcrossThreadsAndRanks) {
  const Problem p(301);
  Vector g_whole;
  const double whole = one_step_loss(*p.map, p.theta, p.pairs, &g_whole);
  // One chunk (301 pairs, the default plan): the whole loss, to the bit, on threads too.
  for (int threads : {1, 2}) {
    ChunkedOneStepLoss one(*p.map, p.pairs, 0, threads, serial_communicator());
    Vector g;
    EXPECT_TRUE(same_bits(one.loss(p.theta, &g), whole));
    EXPECT_TRUE(same_bits(g, g_whole));
    EXPECT_TRUE(same_bits(one.loss(p.theta, nullptr), whole));
  }
  // Chunks of 40: the same sum in another order (close), and the same bits for any workers.
  using Result = std::pair<Vector, Vector>;  // (gradient, [loss, validation loss])
  const auto chunked = [&p](int threads, const Communicator& comm) {
    ChunkedOneStepLoss loss(*p.map, p.pairs, 40, threads, comm);
    EXPECT_EQ(loss.plan().chunks(), 8);
    Vector g;
    Vector l(2);
    l(0) = loss.loss(p.theta, &g);
    l(1) = loss.loss(p.theta, nullptr);
    return Result{g, l};
  };
  const Result serial = chunked(1, serial_communicator());
  EXPECT_NEAR(serial.second(0), whole, 1e-12 * whole);
  EXPECT_TRUE(same_bits(serial.second(0), serial.second(1)));  // with or without a gradient
  EXPECT_LT((serial.first - g_whole).norm(), 1e-12 * g_whole.norm());
  for (int ranks : {1, 2, 3})
    for (int threads : {1, 2, 3}) {
      SCOPED_TRACE(std::to_string(ranks) + " ranks × " + std::to_string(threads) + " threads");
      InProcessRanks all(ranks);
      std::vector<Result> out(static_cast<std::size_t>(ranks));
      std::vector<std::thread> ts;
      for (int r = 0; r < ranks; ++r)
        ts.emplace_back([&, r] {
          const InProcessRanks::Rank comm(all, r);
          out[static_cast<std::size_t>(r)] = chunked(threads, comm);
        });
      for (std::thread& t : ts) t.join();
      for (const Result& o : out) {
        EXPECT_TRUE(same_bits(o.first, serial.first));
        EXPECT_TRUE(same_bits(o.second, serial.second));
      }
    }
}

TEST(ChunkedLoss, MiniBatchTrainingIsTheSameOnAnyThreadsAndRanks) {
  const Problem p(230);
  const PairSet val = Problem(50).pairs;
  const auto train = [&](int threads, const Communicator& comm, long batch, long chunk) {
    TrainOptions o;
    o.epochs = 6;
    o.val_every = 2;
    o.adamw.lr = 1e-2;
    o.batch_size = batch;
    o.shuffle_seed = 9;
    const LossPlan plan{threads, chunk, batch > 0, &comm};
    Vector theta = p.theta;
    const TrainSummary s =
        train_parameters(make_one_step_objective(*p.map, p.pairs, val, plan), theta, o);
    EXPECT_EQ(s.steps, batch > 0 ? 6 * ((230 + batch - 1) / batch) : 6);
    return theta;
  };
  const Vector full = train(1, serial_communicator(), 0, 0);
  // Batches of 64 (four steps an epoch, the last of 38 pairs), in chunks of 16.
  const Vector batched = train(1, serial_communicator(), 64, 16);
  EXPECT_FALSE(same_bits(full, batched));
  EXPECT_TRUE(same_bits(train(1, serial_communicator(), 64, 16), batched));  // reproducible
  EXPECT_TRUE(same_bits(train(3, serial_communicator(), 64, 16), batched));
  for (int ranks : {2, 3})
    EXPECT_TRUE(same_bits(
        on_ranks(ranks, [&](const Communicator& c) { return train(2, c, 64, 16); }), batched));
  // Another shuffle seed, another order of the pairs.
  TrainOptions o;
  o.epochs = 6;
  o.val_every = 2;
  o.adamw.lr = 1e-2;
  o.batch_size = 64;
  o.shuffle_seed = 10;
  Vector theta = p.theta;
  train_parameters(
      make_one_step_objective(*p.map, p.pairs, val, LossPlan{1, 16, true, &serial_communicator()}),
      theta, o);
  EXPECT_FALSE(same_bits(theta, batched));
  // A batch objective is needed for mini-batches.
  theta = p.theta;
  EXPECT_THROW(train_parameters(make_one_step_objective(*p.map, p.pairs, val), theta, o), Error);
}

}  // namespace
}  // namespace csympnet::testing
