// NumPy ↔ Eigen at the binding boundary, and JSON passed as text.
//
// Python sees a batch of states as an (N, 2d) C-order array, one state per row; the library
// sees a 2d x N column-major matrix, one state per column. The two have the same memory
// layout, so a conversion is one copy. The Python layer (csympnet/_records.py) has already
// checked shapes, dtypes and finiteness and explained any problem to the user; the checks here
// only guard the library against a caller that bypasses it.
#pragma once

#include <string>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <nlohmann/json.hpp>

#include "csympnet/core/error.hpp"
#include "csympnet/core/types.hpp"
#include "csympnet/data/dataset.hpp"

namespace csympnet::py_binding {

namespace py = pybind11;

using DArray = py::array_t<double, py::array::c_style | py::array::forcecast>;

// (N, dim) array → dim x N matrix. dim < 0 accepts any width.
inline Matrix states_from(const DArray& a, const std::string& name, Index dim = -1) {
  require(a.ndim() == 2, name + ": expected a 2-D array of states (N, 2d), got " +
                             std::to_string(a.ndim()) + " dimensions");
  const Index n = a.shape(0), width = a.shape(1);
  require(dim < 0 || width == dim, name + ": states have " + std::to_string(width) +
                                       " components, expected 2d = " + std::to_string(dim));
  return Eigen::Map<const Matrix>(a.data(), width, n);
}

// 1-D array of length n (n < 0: any length) → vector.
inline Vector vector_from(const DArray& a, const std::string& name, Index n = -1) {
  require(a.ndim() == 1,
          name + ": expected a 1-D array, got " + std::to_string(a.ndim()) + " dimensions");
  require(n < 0 || a.shape(0) == n,
          name + ": has " + std::to_string(a.shape(0)) + " entries, expected " + std::to_string(n));
  return Eigen::Map<const Vector>(a.data(), a.shape(0));
}

// dim x N matrix → (N, dim) array.
inline DArray states_to(const Matrix& m) {
  DArray out({m.cols(), m.rows()});
  Eigen::Map<Matrix>(out.mutable_data(), m.rows(), m.cols()) = m;
  return out;
}

inline DArray vector_to(const Vector& v) {
  DArray out(v.size());
  Eigen::Map<Vector>(out.mutable_data(), v.size()) = v;
  return out;
}

// Python (t, z) pairs ↔ Trajectory: t is (n+1,), z is (n+1, 2d).
inline std::vector<Trajectory> trajectories_from(const py::sequence& seq, const std::string& name) {
  std::vector<Trajectory> out;
  for (std::size_t k = 0; k < seq.size(); ++k) {
    const std::string where = name + "[" + std::to_string(k) + "]";
    const auto item = seq[k].cast<py::sequence>();
    require(item.size() == 2, where + ": expected a (t, z) pair");
    Trajectory tr;
    tr.t = vector_from(item[0].cast<DArray>(), where + ".t");
    tr.z = states_from(item[1].cast<DArray>(), where + ".z");
    tr.validate(where);
    out.push_back(std::move(tr));
  }
  return out;
}

// Python (t, q) pairs of a record of positions alone → Trajectory whose z holds the d position
// rows, as identify_positions and score_positions take them (no momenta, not even as zeros).
// d < 0 accepts any d; those functions check the values and the times themselves.
inline std::vector<Trajectory> positions_from(const py::sequence& seq, const std::string& name,
                                              Index d = -1) {
  std::vector<Trajectory> out;
  for (std::size_t k = 0; k < seq.size(); ++k) {
    const std::string where = name + "[" + std::to_string(k) + "]";
    const auto item = seq[k].cast<py::sequence>();
    require(item.size() == 2, [&] { return where + ": expected a (t, q) pair"; });
    const DArray q = item[1].cast<DArray>();
    require(q.ndim() == 2, [&] {
      return where + ".q: expected a 2-D array of positions (M, d), got " +
             std::to_string(q.ndim()) + " dimensions";
    });
    require(d < 0 || q.shape(1) == d, [&] {
      return where + ".q: positions have " + std::to_string(q.shape(1)) +
             " columns, expected d = " + std::to_string(d);
    });
    Trajectory tr;
    tr.t = vector_from(item[0].cast<DArray>(), where + ".t");
    tr.z = states_from(q, where + ".q");
    require(tr.z.cols() == tr.t.size(), [&] {
      return where + ": " + std::to_string(tr.z.cols()) + " positions for " +
             std::to_string(tr.t.size()) + " times; expected one time per sample";
    });
    out.push_back(std::move(tr));
  }
  return out;
}

inline py::list trajectories_to(const std::vector<Trajectory>& trajs) {
  py::list out;
  for (const Trajectory& tr : trajs) out.append(py::make_tuple(vector_to(tr.t), states_to(tr.z)));
  return out;
}

inline nlohmann::json parse_json(const std::string& text, const std::string& name) {
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw Error(name + ": not valid JSON (" + e.what() + ")");
  }
}

}  // namespace csympnet::py_binding
