#pragma once
// Anderson acceleration (type II; the same update as IQN-ILS in its fixed-point form) of the coupling loop's
// fixed-point iteration x_{k+1} = G(x_k) = x_k - dx_k, where dx_k is the loop's linear-solve correction.
//
// Given the differences of the last iterates' residuals f_k = G(x_k) - x_k and images G(x_k), the next
// iterate is G(x_k) - dG gamma, with gamma the least-squares solution of min || f_k - dF gamma ||_W. The
// weighted norm W scales each unknown kind (velocity components, pressure) by the inverse of its mean
// magnitude in f_k, so that the pressure, a thousand times larger in cgs units, does not decide alone.
// Columns may be kept from the previous `reuse_steps` time steps (as in IQN-ILS(q)): the map changes little
// from one step to the next, so they describe it from the first iteration of a step on.
//
// Only the iterate changes: the coupling loop still stops on its exact residuals, so the answer is the same
// to the coupling tolerance.
#include <petscvec.h>

#include <deque>
#include <vector>

namespace cellfsi::coupling {

class AndersonAcceleration {
 public:
  /// like: a vector of the iterate's layout; kinds: the kind of each of this rank's entries of it (0, 1, ...:
  /// e.g. velocity components and pressure, fluid::ImmersedFluid::unknown_kinds); columns: most difference
  /// pairs kept (>= 1); reuse_steps: steps whose columns are kept (0: this step's).
  AndersonAcceleration(Vec like, std::vector<int> kinds, int columns, int reuse_steps);
  /// The same with the kinds interleaved per node: entry i of kind i mod block_size (e.g. u, v, p).
  AndersonAcceleration(Vec like, int block_size, int columns, int reuse_steps);
  ~AndersonAcceleration();
  AndersonAcceleration(const AndersonAcceleration&) = delete;
  AndersonAcceleration& operator=(const AndersonAcceleration&) = delete;

  /// Starts a new fixed-point problem (a time step): no difference is formed across the boundary, and
  /// columns older than reuse_steps steps are dropped.
  void begin_step();
  /// x: the iterate x_k on entry, x_{k+1} on return; dx: the correction with G(x_k) = x_k - dx (unchanged).
  void update(Vec x, Vec dx);
  /// Difference pairs in use (after the last update).
  int columns_used() const { return static_cast<int>(cols_.size()); }
  /// Forgets every column (e.g. after a failed step).
  void reset();

 private:
  struct Column {
    Vec df = nullptr, dg = nullptr;
    int step = 0;
  };
  void drop_oldest();
  std::vector<int> kinds_;          // of this rank's entries
  std::vector<double> per_kind_;    // entries of each kind over all ranks
  int max_columns_, reuse_steps_;
  int step_ = 0;
  bool have_previous_ = false;
  Vec f_prev_ = nullptr, g_prev_ = nullptr, f_ = nullptr, g_ = nullptr, w_ = nullptr, wf_ = nullptr;
  std::deque<Column> cols_;
  std::vector<Vec> spare_;  // freed column vectors, reused
  std::vector<Vec> q_;      // orthonormal basis of the scaled columns (workspace)
};

}  // namespace cellfsi::coupling
