// The processes one training runs on, and the few collective operations it needs: an
// all-gather in rank order and an agreement on a flag. One process alone (the default), or the
// ranks of an MPI job when the library is built with MPI (CSYMPNET_WITH_MPI) and the command
// was started by an MPI launcher (`mpirun -np K`). The training code sees only this interface.
#pragma once

#include <string>
#include <vector>

namespace csympnet {

class Communicator {
 public:
  virtual ~Communicator() = default;
  virtual int rank() const = 0;
  virtual int size() const = 0;
  // Every rank's `mine`, concatenated in rank order, on every rank. Collective: every rank
  // calls it the same number of times, in the same order.
  virtual std::vector<double> all_gather(const std::vector<double>& mine) const = 0;
  // Whether `flag` holds on any rank (collective).
  virtual bool any(bool flag) const = 0;
  // Ends every rank of the job with `code` (after a failure on this rank that the others,
  // waiting in a collective, would never learn of). Returns only for a single process.
  virtual void abort(int code) const = 0;
};

// One process: all_gather returns its argument, any() the flag, abort() returns.
class SerialCommunicator final : public Communicator {
 public:
  int rank() const override { return 0; }
  int size() const override { return 1; }
  std::vector<double> all_gather(const std::vector<double>& mine) const override { return mine; }
  bool any(bool flag) const override { return flag; }
  void abort(int /*code*/) const override {}
};

const Communicator& serial_communicator();

// Whether this build can run one training over MPI ranks.
bool built_with_mpi();

// The number of ranks an MPI launcher started this process with (OMPI_COMM_WORLD_SIZE or
// PMI_SIZE), 1 outside a launcher.
int launcher_size();

// This process's communicator: MPI's world when built with MPI and launcher_size() > 1 (MPI is
// initialised on the first call), the serial one otherwise. Throws Error when a launcher
// started several ranks but the build has no MPI: they would each train alone.
const Communicator& process_communicator();

// Whether process_communicator() started MPI (so that finish_process_communicator() must end it
// and a failure must end the job).
bool process_communicator_started();

// Ends MPI if process_communicator() started it; every rank calls it once, at exit.
void finish_process_communicator();

}  // namespace csympnet
