#pragma once
// Stopping a run cleanly. SIGINT (Ctrl-C), SIGTERM (kill, batch systems) and SIGUSR1 (forwarded by mpirun to
// every rank; e.g. Slurm's --signal=USR1@300) ask the run to stop after the time step in progress: the step's
// metrics row, the output series and summary.json (status "interrupted: ...") are written and the process
// exits with 128 + the signal's number. A second signal (any of the three) ends the process at once.
#include <mpi.h>

#include <string>

namespace cellfsi::app {

/// Installs the handlers for SIGINT, SIGTERM and SIGUSR1 (replacing PETSc's: call after PetscInitialize).
/// `announce`: this process prints one line to stderr when a signal arrives (rank 0 only, to avoid one
/// line per rank).
void install_stop_handlers(bool announce);
/// The signal that asked this process to stop (0: none).
int stop_signal();
/// The signal any process of comm received (the largest number; 0: none). Collective.
int agreed_stop_signal(MPI_Comm comm);
/// "SIGINT", "SIGTERM", "SIGUSR1", or "signal N".
std::string signal_name(int signal);

}  // namespace cellfsi::app
