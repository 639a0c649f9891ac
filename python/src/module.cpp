// The compiled half of the csympnet Python package (csympnet._core). The public API, its
// argument checks and its docstrings live in the pure-Python half (python/csympnet/); this
// module only moves arrays across and calls the library.
#include <pybind11/pybind11.h>

#include <cctype>
#include <exception>
#include <string>

#include "csympnet/core/error.hpp"
#include "csympnet/core/options.hpp"
#include "model_binding.hpp"

namespace {
// How Python spells the library's option keys (core/options.hpp): as its keyword arguments,
// which are the keys but for decay_damping (fit's beta_decay=); an option given a value reads
// as a keyword argument: refine="lm", epochs=10.
const csympnet::OptionSpelling& python_spelling() {
  static const csympnet::OptionSpelling s{
      [](const std::string& key) -> std::string {
        return key == "decay_damping" ? "beta_decay" : key;
      },
      [](const std::string& key, const std::string& value) {
        const bool number = !value.empty() && (std::isdigit(static_cast<unsigned char>(value[0])) ||
                                               value[0] == '-' || value[0] == '.');
        return python_spelling().name(key) + "=" + (number ? value : "\"" + value + "\"");
      }};
  return s;
}
}  // namespace

PYBIND11_MODULE(_core, m) {
  namespace py = pybind11;
  m.doc() = "csympnet's C++ library (use the csympnet package, not this module).";
  // The library's one exception type: csympnet.Error, a ValueError, carrying its message.
  static py::exception<csympnet::Error>& error =
      py::register_exception<csympnet::Error>(m, "Error", PyExc_ValueError);
  // An option the library refused: the same csympnet.Error, naming the option as Python
  // spells it ("val_fraction", not the CLI's "--val-fraction"). Registered after Error's
  // translator, so it is tried first.
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const csympnet::OptionError& e) {
      PyErr_SetString(error.ptr(), e.message(python_spelling()).c_str());
    }
  });
  csympnet::py_binding::bind_model(m);
  csympnet::py_binding::bind_fit(m);
  csympnet::py_binding::bind_data(m);
  m.attr("__version__") = CSYMPNET_VERSION;
}
