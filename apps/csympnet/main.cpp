// csympnet: learn conformally symplectic one-step maps of damped Hamiltonian systems and
// identify the damping rate. See `csympnet --help` and README.md.
#include <cstdio>
#include <exception>

#include <CLI/CLI.hpp>

#include "commands.hpp"
#include "csympnet/core/communicator.hpp"
#include "csympnet/core/error.hpp"
#include "interrupt.hpp"
#include "standard_streams.hpp"
#include "system_options.hpp"

namespace {

// Under mpirun (csympnet/core/communicator.hpp) every rank returns here. An outcome all ranks
// share (done, interrupted, not identified, a usage error) ends MPI with them; a failure ends
// the whole job, since the other ranks may be waiting for this one in a collective.
int finish(int code, bool shared) {
  // What went to standard output must have got there (a full disk, a closed stream).
  code = csympnet::cli::finish_standard_output(code);
  if (!csympnet::process_communicator_started()) return code;
  if (!shared) csympnet::process_communicator().abort(code);
  csympnet::finish_process_communicator();
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  csympnet::cli::keep_standard_descriptors_taken();
  CLI::App app{
      "csympnet: conformal-symplectic map learning (CSympNet-ID) and damping identification"};
  csympnet::cli::add_all_commands(app);
  csympnet::cli::install_interrupt_handlers();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // CLI11 prints the message; every usage error exits 2 (CLI11's own codes are 100-127,
    // which scripts cannot tell apart from other failures), --help and --version exit 0.
    return finish(app.exit(e) == 0 ? 0 : 2, true);
  } catch (const csympnet::cli::Interrupted& e) {
    std::fprintf(stderr, "csympnet: interrupted by %s: %s\n", csympnet::cli::interrupt_name(),
                 e.what());
    return finish(csympnet::cli::interrupt_exit_code(), true);
  } catch (const csympnet::cli::NotIdentified& e) {
    std::fprintf(stderr, "csympnet: not identified: %s\n", e.what());
    return finish(csympnet::cli::kNotIdentifiedExitCode, true);
  } catch (const csympnet::cli::ModelRejected& e) {
    std::fprintf(stderr, "csympnet: model rejected: %s\n", e.what());
    return finish(csympnet::cli::kModelRejectedExitCode, true);
  } catch (const csympnet::OptionError& e) {
    // An option the library refused once the data were read (a beta_init too large for the
    // data's steps): named as the command line spells it.
    std::fprintf(stderr, "csympnet: error: %s\n", e.message(csympnet::cli::cli_spelling()).c_str());
    return finish(1, false);
  } catch (const csympnet::Error& e) {
    // After a signal, a failure is its consequence (a read cut short by EINTR): say so, and
    // exit with the signal's code.
    if (csympnet::cli::interrupted()) {
      std::fprintf(stderr, "csympnet: interrupted by %s: %s\n", csympnet::cli::interrupt_name(),
                   e.what());
      return finish(csympnet::cli::interrupt_exit_code(), false);
    }
    std::fprintf(stderr, "csympnet: error: %s\n", e.what());
    return finish(1, false);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "csympnet: internal error: %s\n", e.what());
    return finish(3, false);
  }
  return finish(0, true);
}
