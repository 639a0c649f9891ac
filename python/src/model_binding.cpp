// _core.Model: prediction, rollout, Jacobians and diagnostics of a trained model, and its file.
// Every numerical call releases the GIL; none keeps a pointer into a NumPy buffer after it.
#include "model_binding.hpp"

#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

#include <pybind11/stl.h>

#include "convert.hpp"
#include "csympnet/core/stop.hpp"
#include "csympnet/diagnostics/diagnostics.hpp"
#include "csympnet/diagnostics/learned_map.hpp"
#include "csympnet/diagnostics/observed.hpp"
#include "csympnet/diagnostics/positions_score.hpp"
#include "csympnet/models/model_file.hpp"
#include "csympnet/systems/system.hpp"
#include "csympnet/train/positions_state.hpp"
#include "csympnet/train/shooting.hpp"

namespace csympnet::py_binding {

namespace {

// One step of every column of Z with its own h. By default each column is stepped on its own,
// exactly as `csympnet rollout` steps a state, so a state's result does not depend on the rest of
// the batch. `batched` runs map models in one forward pass over all columns (the pass training
// uses): faster for large N, equal to rounding (Eigen picks other product kernels for many
// columns). Vector-field models always integrate each column (dopri5).
Matrix step_all(const PyModel& m, const Matrix& z, const Vector& h, bool batched) {
  if (batched && m.model.is_map()) return m.model.map->apply(m.theta, z, h);
  const LearnedMap lm = learned_map(m.model, m.theta);
  Matrix out(z.rows(), z.cols());
  for (Index j = 0; j < z.cols(); ++j) out.col(j) = lm.step(z.col(j), h(j));
  return out;
}

DArray predict(const PyModel& m, const DArray& z, const DArray& h, bool batched) {
  const Matrix zs = states_from(z, "z", m.model.dim());
  const Vector hs = vector_from(h, "h", zs.cols());
  Matrix out;
  {
    py::gil_scoped_release nogil;
    out = step_all(m, zs, hs, batched);
  }
  return states_to(out);
}

// The same rollout as `csympnet rollout` and `evaluate` (one learned_map step at a time).
DArray rollout_states(const PyModel& m, const DArray& z0, const DArray& hs) {
  const Vector z = vector_from(z0, "z0", m.model.dim());
  const Vector steps = vector_from(hs, "hs");
  Matrix out;
  {
    py::gil_scoped_release nogil;
    out = rollout(learned_map(m.model, m.theta), z, steps);
  }
  return states_to(out);
}

// The inputs u (n, m) of a map with m inputs as samples (m × n); refused by name when the
// shape does not match.
Matrix input_samples(const PyModel& m, const DArray& u, Index n, const std::string& what) {
  const Index inputs = m.model.is_map() ? m.model.map->n_inputs() : 0;
  if (inputs == 0)
    throw Error(what + ": this model has no inputs (it was fitted to a free record)");
  if (u.ndim() != 2 || u.shape(0) != n || u.shape(1) != inputs)
    throw Error(what + ": u must be (" + std::to_string(n) + ", " + std::to_string(inputs) +
                "), the model's " + std::to_string(inputs) + " input(s) at each of the " +
                std::to_string(n) + " times");
  Matrix out(inputs, n);
  for (Index k = 0; k < n; ++k)
    for (Index j = 0; j < inputs; ++j) {
      out(j, k) = u.at(k, j);
      if (!std::isfinite(out(j, k)))
        throw Error(what + ": u[" + std::to_string(k) + ", " + std::to_string(j) +
                    "] is not finite; expected a finite input at every time");
    }
  return out;
}

// The free run of a driven map from z0 at the times t (n,), fed the inputs u (n, m) at those
// times (held between them as the model holds them): (n, 2d), z0 first. The same steps as
// `csympnet evaluate`'s simulation.
DArray simulate_driven(const PyModel& m, const DArray& z0, const DArray& t, const DArray& u) {
  const Vector z = vector_from(z0, "z0", m.model.dim());
  const Vector ts = vector_from(t, "t");
  const Index n = ts.size();
  if (n < 2) throw Error("simulate: t must hold at least two times (z0's and one more)");
  const Vector steps = ts.tail(n - 1) - ts.head(n - 1);
  for (Index k = 0; k < steps.size(); ++k)
    if (!(std::isfinite(steps(k)) && steps(k) > 0.0))
      throw Error("simulate: t must be finite and increasing; t[" + std::to_string(k + 1) +
                  "] is not after t[" + std::to_string(k) + "]");
  const Matrix us = input_samples(m, u, n, "simulate");
  Matrix out;
  {
    py::gil_scoped_release nogil;
    out = driven_rollout(*m.model.map, m.theta, z, steps, step_inputs(us, 0, n - 1));
  }
  return states_to(out);
}

// The state at the last of a window of positions q (L, d) at times t (L,), its momenta fitted
// with the model (train/shooting.hpp, state_from_positions): (state (2d,), rms residual). A
// driven model takes the window's inputs u (L, m).
py::tuple positions_state(const PyModel& m, const DArray& q, const DArray& t,
                          std::optional<DArray> u) {
  if (!m.model.is_map() || m.model.type() != "csympnet")
    throw Error(
        "state_from_positions: needs a csympnet model (a one-step map with a damping "
        "rate), not '" +
        m.model.type() + "'");
  const Index d = m.model.dim() / 2;
  if (q.ndim() != 2 || q.shape(1) != d)
    throw Error("state_from_positions: q must be (L, " + std::to_string(d) +
                "), the positions of the model's d = " + std::to_string(d) + " coordinates");
  const Index len = q.shape(0);
  Matrix qs(d, len);
  for (Index k = 0; k < len; ++k)
    for (Index i = 0; i < d; ++i) qs(i, k) = q.at(k, i);
  const Vector ts = vector_from(t, "t", len);
  const Index inputs = m.model.map->n_inputs();
  if (inputs > 0 && !u)
    throw Error("state_from_positions: this model is driven by " + std::to_string(inputs) +
                " input(s); give the window's inputs u (L, m)");
  const Matrix us = u ? input_samples(m, *u, len, "state_from_positions") : Matrix();
  double rms = 0.0;
  Vector z;
  {
    py::gil_scoped_release nogil;
    // Refused (csympnet.Error) when the fit does not explain the window, as rollout does.
    z = checked_state_from_positions(*m.model.map, m.theta, qs, ts, &rms, "state_from_positions",
                                     step_inputs(us, 0, len - 1));
  }
  return py::make_tuple(states_to(z), rms);
}

// DΦ̂_h at each state: (N, 2d, 2d), row-major, jac[i, r, c] = ∂Φ_r/∂z_c.
DArray jacobians(const PyModel& m, const DArray& z, const DArray& h) {
  const Matrix zs = states_from(z, "z", m.model.dim());
  const Vector hs = vector_from(h, "h", zs.cols());
  const Index dim = zs.rows();
  DArray out({zs.cols(), dim, dim});
  double* data = out.mutable_data();
  {
    py::gil_scoped_release nogil;
    const LearnedMap lm = learned_map(m.model, m.theta);
    using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
    for (Index j = 0; j < zs.cols(); ++j)
      Eigen::Map<RowMajor>(data + j * dim * dim, dim, dim) = lm.jacobian(zs.col(j), hs(j));
  }
  return out;
}

// Per-state structure diagnostics (diagnostics/diagnostics.hpp): R against exp(−γ h) when the
// true γ is given (else NaN), λ̂, and the self residual S. A state where the Jacobian does not
// exist gives +inf, as in evaluate().
py::tuple structure(const PyModel& m, const DArray& z, const DArray& h,
                    std::optional<double> gamma_true) {
  const Matrix zs = states_from(z, "z", m.model.dim());
  const Vector hs = vector_from(h, "h", zs.cols());
  const Index n = zs.cols();
  Vector r(n), lam(n), self(n);
  {
    py::gil_scoped_release nogil;
    const LearnedMap lm = learned_map(m.model, m.theta);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (Index j = 0; j < n; ++j) {
      const double lambda_star = gamma_true ? std::exp(-*gamma_true * hs(j)) : nan;
      std::optional<double> lambda_own;
      if (lm.gamma_hat) lambda_own = std::exp(-*lm.gamma_hat * hs(j));
      StructureAt s;
      try {
        s = structure_at(lm.jacobian(zs.col(j), hs(j)), lambda_star, lambda_own);
      } catch (const StopRequested&) {
        throw;  // a stop request is not a failure of the map
      } catch (const Error&) {
        const double inf = std::numeric_limits<double>::infinity();
        s = {inf, inf, inf};
      }
      r(j) = gamma_true ? s.residual : nan;
      lam(j) = s.lambda_hat;
      self(j) = s.self_residual;
    }
  }
  return py::make_tuple(vector_to(r), vector_to(lam), vector_to(self));
}

// score_observed() as `csympnet evaluate --data` runs it: (scores as JSON text, rollouts).
py::tuple score_model(const PyModel& m, const py::sequence& data) {
  const std::vector<Trajectory> trajs = trajectories_from(data, "data");
  ObservedScores s;
  {
    py::gil_scoped_release nogil;
    s = score_observed(learned_map(m.model, m.theta), trajs);
  }
  const nlohmann::json scores = s;
  py::list rollouts;
  for (const Matrix& r : s.rollouts) rollouts.append(states_to(r));
  return py::make_tuple(scores.dump(), rollouts);
}

// score_positions() as `csympnet evaluate --data POSITIONS.csv` runs it, on (t (n,), q (n, d))
// pairs: (scores as JSON text, rollouts). The library checks the values, times and lengths.
py::tuple score_positions_model(const PyModel& m, const py::sequence& data,
                                std::optional<long> warmup) {
  const std::vector<Trajectory> trajs = positions_from(data, "data", m.model.dim() / 2);
  PositionsScores s;
  {
    py::gil_scoped_release nogil;
    s = score_positions(m.model, m.theta, trajs, {warmup, "data"});
  }
  const nlohmann::json scores = s;
  py::list rollouts;
  for (const Matrix& r : s.rollouts) rollouts.append(states_to(r));
  return py::make_tuple(scores.dump(), rollouts);
}

// evaluate() as `csympnet evaluate` runs it: returns (scalars as JSON text, rollouts,
// energy_pred, energy_ref).
py::tuple evaluate_model(const PyModel& m, const std::string& system_json,
                         const py::sequence& tests, double h_test) {
  const System sys(parse_json(system_json, "system").get<SystemSpec>());
  require(sys.dim() == m.model.dim(), [&] {
    return "system: phase-space dimension " + std::to_string(sys.dim()) +
           " does not match the model's " + std::to_string(m.model.dim());
  });
  const std::vector<Trajectory> trajs = trajectories_from(tests, "tests");
  Diagnostics d;
  {
    py::gil_scoped_release nogil;
    d = evaluate(learned_map(m.model, m.theta), sys, trajs, h_test);
  }
  const nlohmann::json scalars = d;
  py::list rollouts, e_pred, e_ref;
  for (std::size_t k = 0; k < d.rollouts.size(); ++k) {
    rollouts.append(states_to(d.rollouts[k]));
    e_pred.append(vector_to(d.energy_pred[k]));
    e_ref.append(vector_to(d.energy_ref[k]));
  }
  return py::make_tuple(scalars.dump(), rollouts, e_pred, e_ref);
}

std::unique_ptr<PyModel> from_saved(SavedModel saved) {
  auto out = std::make_unique<PyModel>();
  out->model = std::move(saved.model);
  out->theta = std::move(saved.theta);
  out->meta = saved.meta.is_object() ? saved.meta : nlohmann::json::object();
  // An interval saved by a fit travels in the metadata.
  const auto& ci = out->meta.value("gamma_interval", nlohmann::json());
  if (ci.is_array() && ci.size() == 2 && ci[0].is_number() && ci[1].is_number())
    out->gamma_interval = std::pair{ci[0].get<double>(), ci[1].get<double>()};
  return out;
}

// An instance made by Model.__new__ has no C++ object behind it: pybind11 hands out raw,
// unconstructed storage for it (to be placement-constructed by an __init__ this class does not
// have). So every method takes `self` as a handle and checks that it is a Model whose holder was
// constructed: Python gets an exception, never a crash.
const PyModel& live(py::handle self) {
  if (!py::isinstance<PyModel>(self)) throw py::type_error("expected a csympnet._core.Model");
  auto* inst = reinterpret_cast<py::detail::instance*>(self.ptr());
  auto vh = inst->get_value_and_holder(py::detail::get_type_info(typeid(PyModel)));
  if (!vh.holder_constructed())
    throw std::runtime_error(
        "Model: this object was never constructed; models come from csympnet.fit, "
        "csympnet.identify or csympnet.load");
  return *vh.value_ptr<PyModel>();
}

template <typename R, typename... Args>
auto guarded(R (*f)(const PyModel&, Args...)) {
  return [f](py::handle p, Args... args) { return f(live(p), std::forward<Args>(args)...); };
}

}  // namespace

void bind_model(py::module_& m) {
  py::class_<PyModel>(m, "Model", "A trained model (wrapped by csympnet.Model).")
      .def_property_readonly("type", [](py::handle p) { return live(p).model.type(); })
      .def_property_readonly("dim", [](py::handle p) { return live(p).model.dim(); })
      .def_property_readonly("n_params", [](py::handle p) { return live(p).model.n_params(); })
      .def_property_readonly("is_map", [](py::handle p) { return live(p).model.is_map(); })
      .def_property_readonly("gamma",
                             [](py::handle p) {
                               const PyModel& s = live(p);
                               return s.model.damping_rate(s.theta);
                             })
      .def_property_readonly("gamma_interval", [](py::handle p) { return live(p).gamma_interval; })
      .def_property_readonly("params", [](py::handle p) { return vector_to(live(p).theta); })
      .def_property_readonly("hyperparams_json",
                             [](py::handle p) { return live(p).model.hyperparams().dump(); })
      .def_property_readonly("meta_json", [](py::handle p) { return live(p).meta.dump(); })
      .def_property_readonly("training_json", [](py::handle p) { return live(p).training.dump(); })
      .def("predict", guarded(&predict), py::arg("z"), py::arg("h"), py::arg("batched"))
      .def("rollout", guarded(&rollout_states), py::arg("z0"), py::arg("hs"))
      .def("state_from_positions", guarded(&positions_state), py::arg("q"), py::arg("t"),
           py::arg("u") = py::none())
      .def("simulate", guarded(&simulate_driven), py::arg("z0"), py::arg("t"), py::arg("u"))
      .def_property_readonly("n_inputs",
                             [](py::handle p) {
                               const PyModel& s = live(p);
                               return s.model.is_map() ? s.model.map->n_inputs() : Index{0};
                             })
      .def("jacobian", guarded(&jacobians), py::arg("z"), py::arg("h"))
      .def("structure", guarded(&structure), py::arg("z"), py::arg("h"), py::arg("gamma_true"))
      .def("score", guarded(&score_model), py::arg("data"))
      .def("score_positions", guarded(&score_positions_model), py::arg("data"), py::arg("warmup"))
      .def("evaluate", guarded(&evaluate_model), py::arg("system_json"), py::arg("tests"),
           py::arg("h_test"))
      .def(
          "save",
          [](py::handle p, const std::string& path, const std::string& meta_json) {
            const PyModel& s = live(p);
            const nlohmann::json meta = parse_json(meta_json, "meta");
            require(meta.is_object(), "meta: expected a JSON object");
            py::gil_scoped_release nogil;
            save_model(path, s.model, s.theta, meta);
          },
          py::arg("path"), py::arg("meta_json"))
      .def(
          "to_json",
          [](py::handle p, const std::string& meta_json) {
            const PyModel& s = live(p);
            return model_to_json(s.model, s.theta, parse_json(meta_json, "meta")).dump(1);
          },
          py::arg("meta_json"));

  m.def(
      "load",
      [](const std::string& path) {
        py::gil_scoped_release nogil;
        return from_saved(load_model(path));
      },
      py::arg("path"), "Reads a model file (io/model_file.hpp).");
  m.def(
      "spec_info",
      [](const std::string& spec_json) {
        const Model model = model_from_spec(parse_json(spec_json, "spec"), "spec");
        return py::make_tuple(model.hyperparams().dump(), model.n_params());
      },
      py::arg("spec_json"),
      "(the architecture as the library writes it, its parameter count) of a model spec.");
  m.def(
      "from_spec",
      [](const std::string& spec_json, const DArray& params, const std::string& meta_json) {
        // Through the model file's own reader, so that every check of a file applies (sizes,
        // parameter count, finite values).
        const nlohmann::json spec = parse_json(spec_json, "spec");
        const nlohmann::json meta = parse_json(meta_json, "meta");
        require(meta.is_object(), "meta: expected a JSON object");
        const Vector theta = vector_from(params, "params");
        // In JSON a NaN or an infinity would read as null: name the value here.
        for (Index i = 0; i < theta.size(); ++i)
          require(std::isfinite(theta(i)), [&] {
            return "params[" + std::to_string(i) + "] is " + number_text(theta(i)) +
                   "; expected finite numbers";
          });
        const nlohmann::json doc = {
            {"format", kModelFormat},
            {"version", kModelFormatVersion},
            {"model", spec},
            {"meta", meta},
            {"checksum", model_checksum(spec, meta, theta)},
            {"params", std::vector<double>(theta.data(), theta.data() + theta.size())}};
        return from_saved(model_from_json(doc, "model"));
      },
      py::arg("spec_json"), py::arg("params"), py::arg("meta_json"),
      "A model from its architecture (a model file's \"model\" entry) and flat parameters.");
  m.def(
      "from_json",
      [](const std::string& text) {
        // The file reader's own parse: its bounds on depth and size apply (docs/hardening.md).
        return from_saved(model_from_text(text, "model"));
      },
      py::arg("text"), "Builds a model from the text of a model file.");
}

}  // namespace csympnet::py_binding
