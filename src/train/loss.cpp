#include "csympnet/train/loss.hpp"

#include "csympnet/core/error.hpp"

namespace csympnet {

double one_step_loss(const OneStepMap& map, ConstParams theta, const PairSet& pairs, Vector* grad,
                     ForwardCache* cache) {
  return one_step_loss_part(map, theta, pairs, pairs.size(), grad, cache);
}

double one_step_loss_part(const OneStepMap& map, ConstParams theta, const PairSet& pairs,
                          Index n_mean, Vector* grad, ForwardCache* cache) {
  require(n_mean >= pairs.size(),
          "one_step_loss_part: the mean runs over fewer pairs than the part");
  ForwardCache local;
  ForwardCache* c = grad != nullptr ? (cache != nullptr ? cache : &local) : nullptr;
  // In place: the same elementwise differences and products as `Φ̂ − z1` and `(2/N) r`, without
  // two temporaries per epoch.
  Matrix residual = map.forward(theta, pairs.z0, pairs.h, c);
  residual -= pairs.z1;
  const double n = static_cast<double>(n_mean);
  const double loss = residual.squaredNorm() / n;
  if (grad != nullptr) {
    grad->setZero(map.n_params());
    // dL/dΦ̂ = (2/N)(Φ̂ − z1)
    residual *= 2.0 / n;
    map.backward(theta, *c, residual, *grad, nullptr);
  }
  return loss;
}

LossSplit plan_loss_split(const OneStepMap& map, Index n, ThreadTeam* team) {
  LossSplit split;
  const ColumnSplitPasses* passes = map.column_split();
  if (team == nullptr || team->size() < 2 || passes == nullptr) return split;
  std::vector<Columns> ranges = column_ranges(n, team->size());
  if (ranges.size() < 2 || !passes->splits(n, ranges)) return split;
  split.team = team;
  split.ranges = std::move(ranges);
  return split;
}

double one_step_loss(const OneStepMap& map, ConstParams theta, const PairSet& pairs, Vector* grad,
                     ForwardCache* cache, const LossSplit& split) {
  if (!split.active()) return one_step_loss(map, theta, pairs, grad, cache);
  require(cache != nullptr, "one_step_loss: a split loss needs a cache");
  require(split.ranges.back().end == pairs.size(), [&] {
    return "one_step_loss: the split was planned for " + std::to_string(split.ranges.back().end) +
           " pairs, got " + std::to_string(pairs.size());
  });
  const ColumnSplitPasses& passes = *map.column_split();
  const auto& ranges = split.ranges;
  auto in_range = [&ranges](int part) { return static_cast<std::size_t>(part) < ranges.size(); };
  // The serial loss's operations, elementwise ones on each range's columns, the sum alone.
  passes.prepare(theta, pairs.h, *cache);
  Matrix residual(pairs.z0.rows(), pairs.size());
  split.team->run([&](int part) {
    if (!in_range(part)) return;
    const Columns c = ranges[static_cast<std::size_t>(part)];
    passes.forward_columns(theta, pairs.z0, *cache, residual, c);
    residual.middleCols(c.begin, c.size()) -= pairs.z1.middleCols(c.begin, c.size());
  });
  const double n = static_cast<double>(pairs.size());
  const double loss = residual.squaredNorm() / n;
  if (grad == nullptr) return loss;
  grad->setZero(map.n_params());
  split.team->run([&](int part) {
    if (!in_range(part)) return;
    const Columns c = ranges[static_cast<std::size_t>(part)];
    residual.middleCols(c.begin, c.size()) *= 2.0 / n;  // dL/dΦ̂ = (2/N)(Φ̂ − z1)
    passes.backward_columns(theta, *cache, residual, c);
  });
  const int parts = split.team->size();
  split.team->run([&](int part) { passes.backward_params(theta, *cache, *grad, {part, parts}); });
  passes.backward_finish(theta, *cache, *grad);
  return loss;
}

}  // namespace csympnet
