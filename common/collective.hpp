#pragma once
// Making a failure on some ranks a failure on every rank. A rank that throws while the others go on into a
// collective call (a broadcast, a reduction, the next solve) would leave them waiting for ever: a full disk
// seen by rank 0 alone would hang the run instead of stopping it. These helpers agree on the outcome first,
// so every rank throws the same exception and the caller's error handling runs in step on every rank.
#include <mpi.h>

#include <stdexcept>
#include <string>

namespace cellfsi {

/// A failure every rank of a communicator agreed on (throw_if_any_failed): every rank holds the same message,
/// so one rank reports it.
class CollectiveError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Throws on every rank of comm when `local_error` is non-empty on any rank: std::invalid_argument if
/// `invalid_argument` on the first failing rank, CollectiveError otherwise, with that rank's message.
/// Collective.
inline void throw_if_any_failed(MPI_Comm comm, const std::string& local_error,
                                bool invalid_argument = false) {
  int rank = 0, size = 1;
  MPI_Comm_rank(comm, &rank);
  MPI_Comm_size(comm, &size);
  int first = local_error.empty() ? size : rank;
  MPI_Allreduce(MPI_IN_PLACE, &first, 1, MPI_INT, MPI_MIN, comm);
  if (first == size) return;
  int kind = invalid_argument ? 1 : 2;
  MPI_Bcast(&kind, 1, MPI_INT, first, comm);
  int n = static_cast<int>(local_error.size());
  MPI_Bcast(&n, 1, MPI_INT, first, comm);
  std::string message = local_error;
  message.resize(static_cast<std::size_t>(n));
  MPI_Bcast(message.data(), n, MPI_CHAR, first, comm);
  if (kind == 1) throw std::invalid_argument(message);
  throw CollectiveError(message);
}

/// Runs `work` on every rank of comm and makes its outcome collective (throw_if_any_failed): call it where
/// the work itself may contain collective calls that every rank reaches.
template <class Work>
void on_every_rank(MPI_Comm comm, Work&& work) {
  std::string error;
  bool failed = false, invalid = false;
  try {
    work();
  } catch (const std::invalid_argument& e) {
    failed = invalid = true, error = e.what();
  } catch (const std::exception& e) {
    failed = true, error = e.what();
  }
  if (failed && error.empty()) error = "an error without a message";
  throw_if_any_failed(comm, error, invalid);
}

/// Runs `work` on rank 0 of comm and makes its outcome collective: if it throws, every rank throws the same
/// (std::invalid_argument stays one, anything else becomes CollectiveError), so no rank is left waiting in
/// a collective call that rank 0 never reaches. `work` must not call collectives.
template <class Work>
void on_rank_zero(MPI_Comm comm, Work&& work) {
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  on_every_rank(comm, [&] {
    if (rank == 0) work();
  });
}

}  // namespace cellfsi
