#include "csympnet/core/communicator.hpp"

#include <cstdlib>
#include <memory>

#include "csympnet/core/error.hpp"

#ifdef CSYMPNET_WITH_MPI
#include <mpi.h>
#endif

namespace csympnet {

namespace {

int env_int(const char* name, int fallback) {
  const char* v = std::getenv(name);
  if (v == nullptr || *v == '\0') return fallback;
  char* end = nullptr;
  const long x = std::strtol(v, &end, 10);
  return *end == '\0' && x > 0 && x < 1000000 ? static_cast<int>(x) : fallback;
}

#ifdef CSYMPNET_WITH_MPI
// MPI_COMM_WORLD. Only the thread that created it calls MPI (MPI_THREAD_FUNNELED): the
// training's thread teams compute, the calling thread communicates.
class MpiCommunicator final : public Communicator {
 public:
  MpiCommunicator() {
    int provided = 0;
    MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
  }
  ~MpiCommunicator() override { MPI_Finalize(); }
  int rank() const override { return rank_; }
  int size() const override { return size_; }

  std::vector<double> all_gather(const std::vector<double>& mine) const override {
    require(mine.size() < (1u << 30), "all_gather: message too long for one MPI count");
    const int n = static_cast<int>(mine.size());
    std::vector<int> counts(static_cast<std::size_t>(size_));
    MPI_Allgather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
    std::vector<int> displs(counts.size());
    long total = 0;
    for (std::size_t i = 0; i < counts.size(); ++i) {
      displs[i] = static_cast<int>(total);
      total += counts[i];
    }
    require(total < (1l << 31), "all_gather: gathered message too long for one MPI count");
    std::vector<double> all(static_cast<std::size_t>(total));
    MPI_Allgatherv(mine.data(), n, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE,
                   MPI_COMM_WORLD);
    return all;
  }

  bool any(bool flag) const override {
    int in = flag ? 1 : 0, out = 0;
    MPI_Allreduce(&in, &out, 1, MPI_INT, MPI_LOR, MPI_COMM_WORLD);
    return out != 0;
  }

  void abort(int code) const override { MPI_Abort(MPI_COMM_WORLD, code); }

 private:
  int rank_ = 0;
  int size_ = 1;
};
#endif

std::unique_ptr<Communicator>& started() {
  static std::unique_ptr<Communicator> c;
  return c;
}

}  // namespace

const Communicator& serial_communicator() {
  static const SerialCommunicator c;
  return c;
}

bool built_with_mpi() {
#ifdef CSYMPNET_WITH_MPI
  return true;
#else
  return false;
#endif
}

int launcher_size() {
  return env_int("OMPI_COMM_WORLD_SIZE", env_int("PMI_SIZE", 1));
}

const Communicator& process_communicator() {
  if (started()) return *started();
  if (launcher_size() <= 1) return serial_communicator();
#ifdef CSYMPNET_WITH_MPI
  started() = std::make_unique<MpiCommunicator>();
  return *started();
#else
  throw Error("started by an MPI launcher with " + std::to_string(launcher_size()) +
              " ranks, but this csympnet was built without MPI, so each rank would train alone; "
              "expected a build with MPI (cmake -DCSYMPNET_MPI=ON and libopenmpi-dev) or one "
              "process");
#endif
}

bool process_communicator_started() {
  return started() != nullptr;
}

void finish_process_communicator() {
  started().reset();
}

}  // namespace csympnet
