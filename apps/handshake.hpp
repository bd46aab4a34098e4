#pragma once
// The start-up agreement between the fluid and the solid group of a split job (apps/launch.cpp).
#include <mpi.h>
#include <petscsys.h>

#include <string>

namespace cellfsi::app {

/// Start-up agreement between the fluid and the solid group: each side reports 2 (ready), 1 (stop quietly:
/// -help), 0 (bad input, already reported by that side) or -S (stopped by signal S during its set-up; the
/// fluid side reports it); both learn the other's state. Once only.
class Handshake {
 public:
  explicit Handshake(MPI_Comm inter) : inter_(inter) {}
  /// Returns the other group's state (2 when there is no other group). `options`: this side's effective
  /// options (options.yaml text), handed to the other side (remote_options()).
  int agree(int state, const std::string& options = "") {
    if (inter_ == MPI_COMM_NULL || done_) return 2;
    done_ = true;
    int local = 0, remote = 0;
    MPI_Comm local_comm = PETSC_COMM_WORLD;
    MPI_Allreduce(&state, &local, 1, MPI_INT, MPI_MIN, local_comm);
    MPI_Allreduce(&local, &remote, 1, MPI_INT, MPI_MIN, inter_);
    // The options texts: leader to leader, then to every rank of the group.
    int rank = 0;
    MPI_Comm_rank(local_comm, &rank);
    long n_mine = static_cast<long>(options.size()), n_other = 0;
    if (rank == 0)
      MPI_Sendrecv(&n_mine, 1, MPI_LONG, 0, 1, &n_other, 1, MPI_LONG, 0, 1, inter_, MPI_STATUS_IGNORE);
    MPI_Bcast(&n_other, 1, MPI_LONG, 0, local_comm);
    remote_options_.assign(static_cast<std::size_t>(n_other), ' ');
    if (rank == 0)
      MPI_Sendrecv(options.data(), static_cast<int>(n_mine), MPI_CHAR, 0, 2, remote_options_.data(),
                   static_cast<int>(n_other), MPI_CHAR, 0, 2, inter_, MPI_STATUS_IGNORE);
    MPI_Bcast(remote_options_.data(), static_cast<int>(n_other), MPI_CHAR, 0, local_comm);
    return remote;
  }
  bool done() const { return done_ || inter_ == MPI_COMM_NULL; }
  bool split() const { return inter_ != MPI_COMM_NULL; }
  const std::string& remote_options() const { return remote_options_; }

 private:
  MPI_Comm inter_;
  bool done_ = false;
  std::string remote_options_;
};

}  // namespace cellfsi::app
