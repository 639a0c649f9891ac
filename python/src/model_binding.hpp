// The model object the Python module hands out, and the binding entry points.
#pragma once

#include <optional>
#include <utility>

#include <pybind11/pybind11.h>
#include <nlohmann/json.hpp>

#include "csympnet/core/types.hpp"
#include "csympnet/models/model.hpp"

namespace csympnet::py_binding {

// A trained model: architecture, parameters and the context saved with it (the same triple as
// a model file, io/model_file.hpp), plus what a fit in this process learned about it.
struct PyModel {
  Model model;
  Vector theta;
  nlohmann::json meta = nlohmann::json::object();
  nlohmann::json training;  // TrainSummary of a fit in this process, else null
  std::optional<std::pair<double, double>> gamma_interval;
};

void bind_model(pybind11::module_& m);  // class Model, load
void bind_fit(pybind11::module_& m);    // fit_pairs, run
void bind_data(pybind11::module_& m);   // presets, systems, generation, CSV

}  // namespace csympnet::py_binding
