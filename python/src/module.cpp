// The compiled half of the csympnet Python package (csympnet._core). The public API, its
// argument checks and its docstrings live in the pure-Python half (python/csympnet/); this
// module only moves arrays across and calls the library.
#include <pybind11/pybind11.h>

#include <atomic>
#include <cctype>
#include <chrono>
#include <exception>
#include <string>
#include <thread>

#include "csympnet/core/error.hpp"
#include "csympnet/core/options.hpp"
#include "csympnet/core/stop.hpp"
#include "model_binding.hpp"
#include "signal_poll.hpp"

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
// The library's long stages without a callback (integrators, generation, file reads) poll
// csympnet::stop_requested(): here, on Python's main thread (where Python runs its signal
// handlers), at most every 50 ms (signal_poll.hpp), Python's pending signals. A handler's exception
// (KeyboardInterrupt) is kept and raised when the stopped call returns to Python. Other
// threads never take the GIL here (the main thread may hold it while it waits for them).
std::thread::id g_main_thread;
std::atomic<bool> g_stop_pending{false};
PyObject* g_stop_type = nullptr;  // the handler's exception, owned; touched with the GIL held
PyObject* g_stop_value = nullptr;
PyObject* g_stop_traceback = nullptr;

bool python_stop_poll() {
  if (g_stop_pending.load(std::memory_order_relaxed)) return true;
  if (std::this_thread::get_id() != g_main_thread) return false;
  static csympnet::py_binding::SignalPollClock clock;
  if (!clock.due()) return false;
  pybind11::gil_scoped_acquire gil;
  if (PyErr_CheckSignals() == 0) return false;
  PyErr_Fetch(&g_stop_type, &g_stop_value, &g_stop_traceback);
  g_stop_pending = true;
  return true;
}

// Sets the Python error of a call that stopped on request: the handler's exception.
void raise_stop() {
  g_stop_pending = false;
  if (g_stop_type != nullptr) {
    PyErr_Restore(g_stop_type, g_stop_value, g_stop_traceback);
    g_stop_type = g_stop_value = g_stop_traceback = nullptr;
  } else {
    PyErr_SetNone(PyExc_KeyboardInterrupt);
  }
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
  // A stage that stopped on a signal raises the signal's exception (KeyboardInterrupt); so
  // does any library error after one (a read cut short), as in the CLI. Registered last, so
  // tried first.
  g_main_thread = std::this_thread::get_id();
  csympnet::set_stop_poll(&python_stop_poll);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const csympnet::StopRequested&) {
      raise_stop();
    } catch (const csympnet::Error&) {
      if (!g_stop_pending) throw;
      raise_stop();
    }
  });
  csympnet::py_binding::bind_model(m);
  csympnet::py_binding::bind_fit(m);
  csympnet::py_binding::bind_data(m);
  m.attr("__version__") = CSYMPNET_VERSION;
}
