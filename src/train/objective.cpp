#include "csympnet/train/objective.hpp"

#include "csympnet/core/error.hpp"
#include "csympnet/train/chunked_loss.hpp"
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
                             const LossPlan& plan) {
  Objective o;
  o.n_params = map.n_params();
  o.damping_index = map.damping_param_index();
  o.damping_rate = [&map](const Vector& th) { return map.damping_rate(th); };
  o.train_pairs = train.size();
  const Communicator& comm = plan.comm != nullptr ? *plan.comm : serial_communicator();
  // Each keeps what it needs of the data (its rank's chunks), its own threads and caches.
  auto tr = std::make_shared<ChunkedOneStepLoss>(map, train, plan.chunk_pairs, plan.threads, comm,
                                                 plan.batches);
  auto va = std::make_shared<ChunkedOneStepLoss>(map, val, plan.chunk_pairs, plan.threads, comm);
  o.chunk_pairs = tr->plan().chunk_pairs;
  o.chunks = tr->plan().chunks();
  o.train_loss = [tr](const Vector& th, Vector& grad) { return tr->loss(th, &grad); };
  if (plan.batches)
    o.batch_loss = [tr](const Vector& th, Vector& grad, const std::vector<Index>& batch) {
      return tr->batch_loss(th, batch, &grad);
    };
  o.val_loss = [va](const Vector& th) { return va->loss(th, nullptr); };
  o.bytes_sent = [tr] { return tr->last_bytes_sent(); };
  return o;
}

}  // namespace

Objective make_one_step_objective(const OneStepMap& map, const PairSet& train, const PairSet& val,
                                  int threads) {
  LossPlan plan;
  plan.threads = threads;
  check_training_data(map.dim(), train, val);
  return one_step_objective(map, train, val, plan);
}

Objective make_one_step_objective(const OneStepMap& map, const PairSet& train, const PairSet& val,
                                  const LossPlan& plan) {
  check_training_data(map.dim(), train, val);
  return one_step_objective(map, train, val, plan);
}

Objective make_objective(const Model& model, const PairSet& train, const PairSet& val,
                         int threads) {
  LossPlan plan;
  plan.threads = threads;
  return make_objective(model, train, val, plan);
}

Objective make_objective(const Model& model, const PairSet& train, const PairSet& val,
                         const LossPlan& plan) {
  check_training_data(model.dim(), train, val);
  if (model.is_map()) return one_step_objective(*model.map, train, val, plan);
  require(
      plan.chunk_pairs == 0 && !plan.batches && (plan.comm == nullptr || plan.comm->size() == 1),
      "train: chunks, mini-batches and MPI ranks need a map model (the midpoint loss of a "
      "vector-field model runs whole, in one process)");
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
