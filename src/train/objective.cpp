#include "csympnet/train/objective.hpp"

#include "csympnet/core/error.hpp"
#include "csympnet/train/loss.hpp"
#include "csympnet/train/midpoint_loss.hpp"

namespace csympnet {

Objective make_objective(const Model& model, const PairSet& train, const PairSet& val,
                         int threads) {
  train.validate("training pairs");
  val.validate("validation pairs");
  require(train.dim() == model.dim() && val.dim() == model.dim(), [&] {
    return "train: data dimension " + std::to_string(train.dim()) +
           " does not match the model's phase-space dimension " + std::to_string(model.dim());
  });
  Objective o;
  o.n_params = model.n_params();
  o.damping_index = model.damping_param_index();
  o.damping_rate = [&model](const Vector& th) { return model.damping_rate(th); };
  if (model.is_map()) {
    const OneStepMap* map = model.map.get();
    auto tr = std::make_shared<PairSet>(train);
    auto va = std::make_shared<PairSet>(val);
    auto cache = std::make_shared<ForwardCache>();
    // The team lives as long as the objective; the split is planned once for the batch.
    std::shared_ptr<ThreadTeam> team;
    LossSplit split;
    if (threads > 1) {
      team = std::make_shared<ThreadTeam>(threads);
      split = plan_loss_split(*map, tr->size(), team.get());
      if (!split.active()) team.reset();  // nothing to share: no idle workers
    }
    o.train_loss = [map, tr, cache, team, split](const Vector& th, Vector& grad) {
      return one_step_loss(*map, th, *tr, &grad, cache.get(), split);
    };
    o.val_loss = [map, va](const Vector& th) { return one_step_loss(*map, th, *va); };
  } else {
    const VectorFieldModel* field = model.field.get();
    auto tr = std::make_shared<MidpointData>(midpoint_data(train));
    auto va = std::make_shared<MidpointData>(midpoint_data(val));
    o.train_loss = [field, tr](const Vector& th, Vector& grad) {
      return midpoint_loss(*field, th, *tr, &grad);
    };
    o.val_loss = [field, va](const Vector& th) { return midpoint_loss(*field, th, *va); };
  }
  return o;
}

TrainSummary train_model(const Model& model, Vector& theta, const PairSet& train,
                         const PairSet& val, const TrainOptions& options,
                         const ProgressCallback& progress) {
  options.validate();
  return train_parameters(make_objective(model, train, val, options.threads), theta, options,
                          progress);
}

}  // namespace csympnet
