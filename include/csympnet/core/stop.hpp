// A process-wide stop request for the long stages that take no callback of their own:
// adaptive integrators, data generation, reading and parsing files. The CLI points it at its
// SIGINT/SIGTERM flag, the Python module at Python's pending signals; with no poll set,
// nothing ever stops (a library user who wants Ctrl-C sets one).
#pragma once

#include <string>

#include "csympnet/core/error.hpp"

namespace csympnet {

// Thrown by a stage that stopped because a stop was requested. An Error, so every caller that
// reports errors reports it too; the CLI exits 130/143, Python raises KeyboardInterrupt.
class StopRequested : public Error {
 public:
  using Error::Error;
};

using StopPoll = bool (*)();

// Sets the function polled by stop_requested() (nullptr: none). Not thread-safe with respect
// to concurrent polls: set it once, before any work.
void set_stop_poll(StopPoll poll);

// True once a stop has been requested. Cheap: the polls above read a flag (the Python poll
// looks at Python's signals only every few milliseconds).
bool stop_requested();

// Throws StopRequested("<what> stopped on request") when a stop has been requested.
void throw_if_stop_requested(const std::string& what);

}  // namespace csympnet
