#pragma once
// Fluid and solids in different MPI processes (docs/design.md §2): the solid ranks own the bodies and serve
// requests; on the fluid ranks each body is a RemoteSolid, a SolidSolver whose calls travel to the body's
// owner and back. FsiCoupler, the metrics and the output use it exactly like a body in their own process, so
// both launch modes compute the same numbers (the payloads are the same doubles).
//
// Transport (Exchange): between two ranks of one node the payload goes through MPI-3 shared memory (each rank
// exposes a mailbox in a window from MPI_Win_allocate_shared; the sender copies into the receiver's mailbox
// and a small MPI message carries the header and orders the accesses); otherwise, or when a payload does not
// fit the mailbox, it goes as an MPI message over the intercommunicator.
//
// Requests are strictly request-reply from fluid rank 0 to one solid rank at a time, so a mailbox has one
// writer at a time and a reader that has finished with it before it is written again. Every fluid rank calls
// the RemoteSolid methods (collectively); rank 0 talks to the solid side and broadcasts the reply.
#include <mpi.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "solid/solid_solver.hpp"

namespace cellfsi::coupling {

class Exchange {
 public:
  /// Collective over both groups of `inter`. mailbox_bytes: shared-memory mailbox per rank (0: messages
  /// only).
  Exchange(MPI_Comm inter, std::size_t mailbox_bytes);
  ~Exchange();
  Exchange(const Exchange&) = delete;
  Exchange& operator=(const Exchange&) = delete;

  struct Message {
    int op = 0, body = 0;
    std::vector<double> data;
  };
  /// Sends to rank `peer` of the remote group.
  void send(int peer, int op, int body, const std::vector<double>& data);
  /// Receives from rank `peer` of the remote group (MPI_ANY_SOURCE not allowed: replies are ordered).
  Message recv(int peer);
  /// True if the payloads to/from this peer go through shared memory.
  bool shared_with(int peer) const;
  MPI_Comm inter() const { return inter_; }
  int local_size() const { return local_size_; }
  int remote_size() const { return remote_size_; }
  /// Bytes moved through shared memory and as messages so far (for the run's statistics).
  std::uint64_t shared_bytes() const { return shared_bytes_; }
  std::uint64_t message_bytes() const { return message_bytes_; }

 private:
  MPI_Comm inter_, merged_ = MPI_COMM_NULL, node_ = MPI_COMM_NULL;
  MPI_Win win_ = MPI_WIN_NULL;
  std::size_t capacity_ = 0;  // doubles per mailbox
  int local_size_ = 0, remote_size_ = 0;
  bool low_ = true;                    // this group comes first in merged_
  std::vector<int> remote_node_rank_;  // rank in node_ of each remote rank, -1 if on another node
  double* mine_ = nullptr;
  std::uint64_t shared_bytes_ = 0, message_bytes_ = 0;
};

/// Operations of the protocol.
enum class SolidOp : int {
  hello = 1,
  begin_step,
  collocation_points,
  kinematic_update,
  quadrature_data,
  interface_points,
  end_step,
  set_rate,
  current_patch,
  cauchy_stress,
  state,
  set_state,
  shutdown,
  error = 99
};

/// Owner of body `index` among `n_solid_ranks` solid ranks.
inline int body_owner(int index, int n_solid_ranks) { return index % n_solid_ranks; }

/// A body on the solid ranks, seen from the fluid ranks. `reference` must be the body's reference patch as
/// the solid side built it (both sides build it from the same scene; hello() checks that they agree).
class RemoteSolid final : public solid::SolidSolver {
 public:
  RemoteSolid(Exchange& exchange, MPI_Comm fluid_comm, int index, std::string name, geometry::Patch reference,
              bool membrane);
  /// Checks that the solid side has the same body (number of points and control points); throws if not.
  void hello();

  std::string name() const override { return name_; }
  int dim() const override { return reference_.physical_dim(); }
  void begin_step(const solid::TimeParameters& time) override;
  std::vector<solid::Vec3> collocation_points() const override;
  double kinematic_update(const std::vector<solid::VelocitySample>& samples) override;
  using solid::SolidSolver::quadrature_data;  // (the selective one: every point, computed remotely)
  std::vector<solid::QuadratureData> quadrature_data(double fluid_density, bool with_tangent) const override;
  std::vector<solid::Vec3> interface_points() const override;
  void end_step() override;
  void set_rate(const std::vector<solid::Vec3>& rate) override;
  std::vector<double> state() const override;
  void set_state(const std::vector<double>& state) override;
  bool is_membrane() const override { return membrane_; }
  geometry::Patch reference_patch() const override { return reference_; }
  geometry::Patch current_patch() const override;
  std::vector<solid::Mat3> cauchy_stress(const std::vector<geometry::Param>& xi) const override;

 private:
  std::vector<double> call(SolidOp op, const std::vector<double>& data) const;
  Exchange& ex_;
  MPI_Comm comm_;
  int index_, owner_;
  std::string name_;
  geometry::Patch reference_;
  bool membrane_;
};

/// The solid side's loop: serves requests for `bodies` (global index -> body, null where another rank owns
/// it) until fluid rank 0 sends shutdown. A body that throws replies with the error, which the fluid side
/// raises as std::runtime_error.
void serve_solids(Exchange& exchange, const std::vector<solid::SolidSolver*>& bodies);
/// Fluid side: tells every solid rank to stop (call on every fluid rank; rank 0 sends).
void shutdown_solids(Exchange& exchange, MPI_Comm fluid_comm);

}  // namespace cellfsi::coupling
