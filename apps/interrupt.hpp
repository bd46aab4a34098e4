#pragma once
// Stopping a run cleanly. SIGINT (Ctrl-C), SIGTERM (kill, batch systems), SIGHUP (the terminal or ssh session
// closed) and SIGUSR1 (forwarded by mpirun to every rank; e.g. Slurm's --signal=USR1@300) ask the run to
// stop: during the time steps after the step in progress (the step's metrics row, the output series, a
// checkpoint and summary.json with status "interrupted: ..." are written), during the set-up at the next
// phase of it. The process exits with 128 + the signal's number. A second such signal ends the process at
// once. SIGPIPE (standard output or error read by a pipe whose reader is gone, e.g. `cellfsi ... | head`)
// stops the run the same way, and what the process prints to the dead stream from then on goes to /dev/null.
#include <mpi.h>

#include <string>

namespace cellfsi::app {

/// Call before MPI and PETSc start (they install handlers of their own): notes the stop signals the process
/// was started with ignored (nohup ignores SIGHUP, a shell's background job SIGINT); those stay ignored.
void record_ignored_signals();
/// Installs the handlers for SIGINT, SIGTERM, SIGHUP, SIGUSR1 and SIGPIPE (replacing PETSc's: call after
/// PetscInitialize). `announce`: this process prints one line to stderr when a signal arrives (rank 0 only,
/// to avoid one line per rank).
void install_stop_handlers(bool announce);
/// From here on a stop request is honoured after the step in progress (before: during the set-up, when there
/// is no step yet); it changes what the announcement says.
void mark_time_stepping();
/// The signal that asked this process to stop (0: none).
int stop_signal();
/// The signal any process of comm received (the largest number; 0: none). Collective.
int agreed_stop_signal(MPI_Comm comm);
/// "SIGINT", "SIGTERM", "SIGHUP", "SIGPIPE", "SIGUSR1", or "signal N".
std::string signal_name(int signal);

}  // namespace cellfsi::app
