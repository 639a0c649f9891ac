#include "csympnet/train/objective.hpp"

#include "csympnet/core/error.hpp"
#include "csympnet/train/loss.hpp"
#include "csympnet/train/midpoint_loss.hpp"

namespace csympnet {

namespace {

void check_training_data(Index dim, const PairSet& train, const PairSet& val) {
  train.validate("training pairs");
  val.validate("validation pairs");
  require(train.dim() == dim && val.dim() == dim, [&] {
    return "train: data dimension " + std::to_string(train.dim()) +
           " does not match the model's phase-space dimension " + std::to_string(dim);
  });
}

// The one-step objective of `map` on data already checked.
Objective one_step_objective(const OneStepMap& map, const PairSet& train, const PairSet& val,
                             int threads) {
  Objective o;
  o.n_params = map.n_params();
  o.damping_index = map.damping_param_index();
  o.damping_rate = [&map](const Vector& th) { return map.damping_rate(th); };
  auto tr = std::make_shared<PairSet>(train);
  auto va = std::make_shared<PairSet>(val);
  auto cache = std::make_shared<ForwardCache>();
  // The team lives as long as the objective; the split is planned once for the batch.
  std::shared_ptr<ThreadTeam> team;
  LossSplit split;
  if (threads > 1) {
    team = std::make_shared<ThreadTeam>(threads);
    split = plan_loss_split(map, tr->size(), team.get());
    if (!split.active()) team.reset();  // nothing to share: no idle workers
  }
  const OneStepMap* m = &map;
  o.train_loss = [m, tr, cache, team, split](const Vector& th, Vector& grad) {
    return one_step_loss(*m, th, *tr, &grad, cache.get(), split);
  };
  o.val_loss = [m, va](const Vector& th) { return one_step_loss(*m, th, *va); };
  return o;
}

}  // namespace

Objective make_one_step_objective(const OneStepMap& map, const PairSet& train, const PairSet& val,
                                  int threads) {
  check_training_data(map.dim(), train, val);
  return one_step_objective(map, train, val, threads);
}

Objective make_objective(const Model& model, const PairSet& train, const PairSet& val,
                         int threads) {
  check_training_data(model.dim(), train, val);
  if (model.is_map()) return one_step_objective(*model.map, train, val, threads);
  Objective o;
  o.n_params = model.n_params();
  o.damping_index = model.damping_param_index();
  o.damping_rate = [&model](const Vector& th) { return model.damping_rate(th); };
  const VectorFieldModel* field = model.field.get();
  auto tr = std::make_shared<MidpointData>(midpoint_data(train));
  auto va = std::make_shared<MidpointData>(midpoint_data(val));
  o.train_loss = [field, tr](const Vector& th, Vector& grad) {
    return midpoint_loss(*field, th, *tr, &grad);
  };
  o.val_loss = [field, va](const Vector& th) { return midpoint_loss(*field, th, *va); };
  return o;
}

}  // namespace csympnet
