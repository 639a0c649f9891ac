// The compiled half of the csympnet Python package (csympnet._core). The public API, its
// argument checks and its docstrings live in the pure-Python half (python/csympnet/); this
// module only moves arrays across and calls the library.
#include <pybind11/pybind11.h>

#include "csympnet/core/error.hpp"
#include "model_binding.hpp"

PYBIND11_MODULE(_core, m) {
  namespace py = pybind11;
  m.doc() = "csympnet's C++ library (use the csympnet package, not this module).";
  // The library's one exception type: csympnet.Error, a ValueError, carrying its message.
  py::register_exception<csympnet::Error>(m, "Error", PyExc_ValueError);
  csympnet::py_binding::bind_model(m);
  csympnet::py_binding::bind_fit(m);
  csympnet::py_binding::bind_data(m);
  m.attr("__version__") = CSYMPNET_VERSION;
}
