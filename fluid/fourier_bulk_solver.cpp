#include "fluid/fourier_bulk_solver.hpp"

#include <unsupported/Eigen/FFT>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "common/petsc_error.hpp"

extern "C" {
// LAPACK (Fortran calling convention; the trailing length is that of the character argument).
void zgbtrf_(const int* m, const int* n, const int* kl, const int* ku, std::complex<double>* ab,
             const int* ldab, int* ipiv, int* info);
void zgbtrs_(const char* trans, const int* n, const int* kl, const int* ku, const int* nrhs,
             const std::complex<double>* ab, const int* ldab, const int* ipiv, std::complex<double>* b,
             const int* ldb, int* info, std::size_t trans_len);
}

namespace cellfsi::fluid {

FourierBulkSolver::FourierBulkSolver(std::array<int, 3> n, std::array<bool, 3> periodic,
                                     std::array<int, 3> degree, int dof)
    : n_(n), degree_(degree), periodic_(periodic), dof_(dof) {
  if (dof < 1) throw std::invalid_argument("FourierBulkSolver: dof must be >= 1");
  for (int d = 0; d < 3; ++d) {
    if (n_[d] < 1) throw std::invalid_argument("FourierBulkSolver: a direction has no control points");
    if (n_[d] == 1) periodic_[d] = false;
    if (n_[d] > 1 && !periodic_[d]) {
      if (across_ >= 0)
        throw std::invalid_argument("FourierBulkSolver: the box has two non-periodic directions (" +
                                    std::to_string(across_) + " and " + std::to_string(d) +
                                    "); the Fourier bulk solver needs all but one periodic");
      across_ = d;
    }
    n_nodes_ *= n_[d];
    if (periodic_[d]) n_modes_ *= n_[d];
    // Columns of a row lie within +-degree nodes; a short periodic direction wraps them onto each other.
    width_[d] = periodic_[d] ? std::min(n_[d], 2 * degree_[d] + 1) : 1;
  }
  n_across_ = across_ >= 0 ? n_[across_] : 1;
  m_ = n_across_ * dof_;
  kl_ = across_ >= 0 ? std::min(m_ - 1, (degree_[across_] + 1) * dof_ - 1) : m_ - 1;
}

long FourierBulkSolver::stencil_index(int j, int c, const std::array<int, 3>& o, int dj, int c2) const {
  const int wq = across_ >= 0 ? 2 * degree_[across_] + 1 : 1;
  long k = static_cast<long>(j) * dof_ + c;
  for (int d = 0; d < 3; ++d) k = k * width_[d] + o[d];
  return (k * wq + dj) * dof_ + c2;
}

bool FourierBulkSolver::offset(int row_node, int col_node, std::array<int, 3>& o, int& j, int& dj) const {
  int r = row_node, c = col_node;
  j = 0;
  dj = 0;
  for (int d = 0; d < 3; ++d) {
    const int ir = r % n_[d], ic = c % n_[d];
    r /= n_[d];
    c /= n_[d];
    o[d] = 0;
    if (periodic_[d]) {
      int diff = ((ic - ir) % n_[d] + n_[d]) % n_[d];
      if (width_[d] < n_[d]) {  // offsets -degree..degree
        if (diff > n_[d] / 2) diff -= n_[d];
        if (std::abs(diff) > degree_[d]) return false;
        diff += degree_[d];
      }
      o[d] = diff;
    } else if (d == across_) {
      j = ir;
      dj = ic - ir;
      if (std::abs(dj) > degree_[d]) return false;
      dj += degree_[d];
    }
  }
  return true;
}

void FourierBulkSolver::build(Mat A, bool pin_pressure) {
  built_ = false;
  PetscInt rows = 0, cols = 0;
  CELLFSI_PETSC(MatGetSize(A, &rows, &cols));
  if (rows != static_cast<PetscInt>(n_nodes_) * dof_ || cols != rows)
    throw std::invalid_argument("FourierBulkSolver: the matrix has " + std::to_string(rows) + " rows, not " +
                                std::to_string(n_nodes_ * dof_));
  const int wq = across_ >= 0 ? 2 * degree_[across_] + 1 : 1;
  stencil_.assign(static_cast<std::size_t>(m_) * width_[0] * width_[1] * width_[2] * wq * dof_, 0.0);
  // 1. The stencil averaged over the periodic positions (n_nodes / n_across rows per (j, c)). A pinned
  // pressure row (-fluid_pressure_null_space false) is averaged in too: its layer's average then carries 1/N
  // of the pin, every node of that layer differs from the bulk operator and the caller's region takes the
  // layer (measured: capsule 64 x 32, 5 steps, theta as the band solver's to 1e-11). Keeping the pin out of
  // the average changed only round-off, yet turned the rigid-disk example (tests/external), whose residual is
  // partly outside the range of its singular Jacobian, from converging to 500 iterations at step 9.
  auto for_each_entry = [&](auto&& f) {
    for (PetscInt row = 0; row < rows; ++row) {
      PetscInt nc = 0;
      const PetscInt* ci = nullptr;
      const PetscScalar* v = nullptr;
      CELLFSI_PETSC(MatGetRow(A, row, &nc, &ci, &v));
      f(row, nc, ci, v);
      CELLFSI_PETSC(MatRestoreRow(A, row, &nc, &ci, &v));
    }
  };
  auto unit_row = [](PetscInt row, PetscInt nc, const PetscInt* ci, const PetscScalar* v) {
    int nonzeros = 0;
    bool diagonal_one = false;
    for (PetscInt k = 0; k < nc; ++k)
      if (v[k] != 0) {
        ++nonzeros;
        diagonal_one = ci[k] == row && v[k] == 1.0;
      }
    return nonzeros == 1 && diagonal_one;
  };
  const double per_row = 1.0 / (n_nodes_ / n_across_);
  std::array<int, 3> o{};
  int j = 0, dj = 0;
  std::vector<char> has_unit(m_, 0);  // classes (j, c) with a unit row
  for_each_entry([&](PetscInt row, PetscInt nc, const PetscInt* ci, const PetscScalar* v) {
    const int node = static_cast<int>(row / dof_), c = static_cast<int>(row % dof_);
    if (unit_row(row, nc, ci, v)) has_unit[across_coordinate(node) * dof_ + c] = 1;
    for (PetscInt k = 0; k < nc; ++k) {
      if (!offset(node, static_cast<int>(ci[k] / dof_), o, j, dj)) {
        if (v[k] == 0) continue;  // the matrix's pattern is the largest degree's in every direction
        throw std::invalid_argument("FourierBulkSolver: row " + std::to_string(row) +
                                    " couples beyond the stencil");
      }
      stencil_[stencil_index(j, c, o, dj, static_cast<int>(ci[k] % dof_))] += v[k] * per_row;
    }
  });
  // 2. How far A is from its average.
  deviation_ = 0;
  for_each_entry([&](PetscInt row, PetscInt nc, const PetscInt* ci, const PetscScalar* v) {
    const int node = static_cast<int>(row / dof_), c = static_cast<int>(row % dof_);
    double row_max = 0, dev = 0;
    // The walls' rows, and the layer of a pinned pressure (its class's average carries 1/N of the pin; the
    // caller's region takes that layer).
    if (has_unit[across_coordinate(node) * dof_ + c]) return;
    for (PetscInt k = 0; k < nc; ++k) {
      if (!offset(node, static_cast<int>(ci[k] / dof_), o, j, dj)) continue;  // a zero (checked above)
      row_max = std::max(row_max, std::abs(v[k]));
      dev = std::max(dev,
                     std::abs(v[k] - stencil_[stencil_index(j, c, o, dj, static_cast<int>(ci[k] % dof_))]));
    }
    if (row_max > 0) deviation_ = std::max(deviation_, dev / row_max);
  });
  // 3. One banded system per wave vector k: A_k[(j, c), (j + dj, c2)] = sum_o a_o exp(i 2 pi k . o / n).
  // A is real, so A_{-k} = conj(A_k): only one of each pair {k, -k} is factorised (its slot).
  slot_.assign(n_modes_, -1);
  int n_slots = 0;
  for (int mode = 0; mode < n_modes_; ++mode)
    if (mirror(mode) >= mode) slot_[mode] = n_slots++;
  const int ldab = 2 * kl_ + kl_ + 1;
  ab_.assign(static_cast<std::size_t>(n_slots) * ldab * m_, cplx(0, 0));
  ipiv_.assign(static_cast<std::size_t>(n_slots) * m_, 0);
  pinned_ = pin_pressure;
  const double two_pi = 2 * std::acos(-1.0);
  std::vector<cplx> phase(static_cast<std::size_t>(width_[0]) * width_[1] * width_[2]);
  for (int mode = 0; mode < n_modes_; ++mode) {
    if (slot_[mode] < 0) continue;
    std::array<int, 3> k{};
    int rest = mode;
    for (int d = 0; d < 3; ++d)
      if (periodic_[d]) {
        k[d] = rest % n_[d];
        rest /= n_[d];
      }
    for (int o0 = 0; o0 < width_[0]; ++o0)
      for (int o1 = 0; o1 < width_[1]; ++o1)
        for (int o2 = 0; o2 < width_[2]; ++o2) {
          const std::array<int, 3> oo{o0, o1, o2};
          double angle = 0;
          for (int d = 0; d < 3; ++d)
            if (periodic_[d]) {
              const int off = width_[d] < n_[d] ? oo[d] - degree_[d] : oo[d];
              angle += two_pi * static_cast<double>(k[d]) * off / n_[d];
            }
          phase[(o0 * width_[1] + o1) * width_[2] + o2] = std::polar(1.0, angle);
        }
    cplx* ab = &ab_[static_cast<std::size_t>(slot_[mode]) * ldab * m_];
    const bool pin = pin_pressure && mode == 0;
    const int pin_row = dof_ - 1;  // the pressure of the first layer
    for (int jj = 0; jj < n_across_; ++jj)
      for (int c = 0; c < dof_; ++c) {
        const int r = jj * dof_ + c;
        if (pin && r == pin_row) continue;
        for (int o0 = 0; o0 < width_[0]; ++o0)
          for (int o1 = 0; o1 < width_[1]; ++o1)
            for (int o2 = 0; o2 < width_[2]; ++o2)
              for (int d2 = 0; d2 < wq; ++d2) {
                const int jc = jj + d2 - (across_ >= 0 ? degree_[across_] : 0);
                if (jc < 0 || jc >= n_across_) continue;
                for (int c2 = 0; c2 < dof_; ++c2) {
                  const double a = stencil_[stencil_index(jj, c, {o0, o1, o2}, d2, c2)];
                  if (a == 0) continue;
                  const int col = jc * dof_ + c2;
                  ab[(2 * kl_ + r - col) + static_cast<std::size_t>(col) * ldab] +=
                      a * phase[(o0 * width_[1] + o1) * width_[2] + o2];
                }
              }
      }
    if (pin) ab[(2 * kl_) + static_cast<std::size_t>(pin_row) * ldab] = 1.0;
    int info = 0;
    zgbtrf_(&m_, &m_, &kl_, &kl_, ab, &ldab, &ipiv_[static_cast<std::size_t>(slot_[mode]) * m_], &info);
    if (info != 0)
      throw std::runtime_error("FourierBulkSolver: the system of wave vector " + std::to_string(mode) +
                               " is singular (LAPACK zgbtrf info " + std::to_string(info) + ")");
  }
  built_ = true;
}

int FourierBulkSolver::across_coordinate(int node) const {
  if (across_ < 0) return 0;
  int stride = 1;
  for (int d = 0; d < across_; ++d) stride *= n_[d];
  return (node / stride) % n_across_;
}

int FourierBulkSolver::mirror(int mode) const {
  int m = 0, stride = 1;
  for (int d = 0; d < 3; ++d)
    if (periodic_[d]) {
      const int k = mode % n_[d];
      mode /= n_[d];
      m += ((n_[d] - k) % n_[d]) * stride;
      stride *= n_[d];
    }
  return m;
}

void FourierBulkSolver::fft(std::vector<cplx>& z, bool inverse) const {
  Eigen::FFT<double> engine;
  std::vector<cplx> line, out;
  int stride = dof_;
  for (int d = 0; d < 3; ++d) {
    if (periodic_[d]) {
      const int n = n_[d];
      line.resize(n);
      out.resize(n);
      const int outer = n_nodes_ * dof_ / (stride * n);
      for (int a = 0; a < outer; ++a)
        for (int b = 0; b < stride; ++b) {
          const std::size_t base = static_cast<std::size_t>(a) * stride * n + b;
          for (int i = 0; i < n; ++i) line[i] = z[base + static_cast<std::size_t>(i) * stride];
          if (inverse)
            engine.inv(out, line);
          else
            engine.fwd(out, line);
          for (int i = 0; i < n; ++i) z[base + static_cast<std::size_t>(i) * stride] = out[i];
        }
    }
    stride *= n_[d];
  }
}

void FourierBulkSolver::solve(Vec r, Vec x) const {
  if (!built_) throw std::logic_error("FourierBulkSolver: solve before a completed build");
  static const PetscLogEvent event = register_log_event("cellfsi fluid", "FluidFourierSolve");
  CELLFSI_PETSC(PetscLogEventBegin(event, 0, 0, 0, 0));
  const std::size_t N = static_cast<std::size_t>(n_nodes_) * dof_;
  std::vector<cplx> z(N);
  {
    const PetscScalar* ra = nullptr;
    CELLFSI_PETSC(VecGetArrayRead(r, &ra));
    for (std::size_t i = 0; i < N; ++i) z[i] = ra[i];
    CELLFSI_PETSC(VecRestoreArrayRead(r, &ra));
  }
  fft(z, false);
  const int ldab = 3 * kl_ + 1, one = 1;
  std::vector<cplx> b(m_);
  // Node index of (the periodic coordinates of a mode, across coordinate j).
  auto node_of = [&](int mode, int jj) {
    std::array<int, 3> i{};
    for (int d = 0; d < 3; ++d)
      if (periodic_[d]) {
        i[d] = mode % n_[d];
        mode /= n_[d];
      }
    if (across_ >= 0) i[across_] = jj;
    return (static_cast<std::size_t>(i[2]) * n_[1] + i[1]) * n_[0] + i[0];
  };
  for (int mode = 0; mode < n_modes_; ++mode) {
    const int slot = slot_[mode];
    if (slot < 0) continue;  // solved with its mirror
    for (int jj = 0; jj < n_across_; ++jj)
      for (int c = 0; c < dof_; ++c) b[jj * dof_ + c] = z[node_of(mode, jj) * dof_ + c];
    if (pinned_ && mode == 0) b[dof_ - 1] = 0.0;
    int info = 0;
    zgbtrs_("N", &m_, &kl_, &kl_, &one, &ab_[static_cast<std::size_t>(slot) * ldab * m_], &ldab,
            &ipiv_[static_cast<std::size_t>(slot) * m_], b.data(), &m_, &info, 1);
    // r is real: the coefficients of -k are the conjugates of those of k.
    const int other = mirror(mode);
    for (int jj = 0; jj < n_across_; ++jj)
      for (int c = 0; c < dof_; ++c) {
        z[node_of(mode, jj) * dof_ + c] = b[jj * dof_ + c];
        if (other != mode) z[node_of(other, jj) * dof_ + c] = std::conj(b[jj * dof_ + c]);
      }
  }
  fft(z, true);
  PetscScalar* xa = nullptr;
  CELLFSI_PETSC(VecGetArray(x, &xa));
  for (std::size_t i = 0; i < N; ++i) xa[i] = z[i].real();
  CELLFSI_PETSC(VecRestoreArray(x, &xa));
  CELLFSI_PETSC(PetscLogEventEnd(event, 0, 0, 0, 0));
}

std::vector<double> FourierBulkSolver::node_deviation(Mat J) const {
  std::vector<double> dev(n_nodes_, 0.0);
  // The largest averaged entry of each (j, c) row.
  const int wq = across_ >= 0 ? 2 * degree_[across_] + 1 : 1;
  const std::size_t per = static_cast<std::size_t>(width_[0]) * width_[1] * width_[2] * wq * dof_;
  std::vector<double> row_max(m_, 0.0);
  for (int r = 0; r < m_; ++r)
    for (std::size_t k = 0; k < per; ++k) row_max[r] = std::max(row_max[r], std::abs(stencil_[r * per + k]));
  PetscInt rows = 0;
  CELLFSI_PETSC(MatGetSize(J, &rows, nullptr));
  std::array<int, 3> o{};
  int j = 0, dj = 0;
  // A SeqBAIJ matrix with node blocks is read block by block from its arrays (MatGetRow would expand every
  // block row: 1 s per call at 32^3 quadratic in 3D).
  PetscBool baij = PETSC_FALSE;
  CELLFSI_PETSC(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(J), MATSEQBAIJ, &baij));
  PetscInt bs = 1;
  CELLFSI_PETSC(MatGetBlockSize(J, &bs));
  if (baij && bs == dof_) {
    PetscInt nb = 0;
    const PetscInt *ia = nullptr, *ja = nullptr;
    PetscBool done = PETSC_FALSE;
    CELLFSI_PETSC(MatGetRowIJ(J, 0, PETSC_FALSE, PETSC_TRUE, &nb, &ia, &ja, &done));
    if (!done) throw std::runtime_error("FourierBulkSolver: the matrix gives no block structure");
    PetscScalar* a = nullptr;
    CELLFSI_PETSC(MatSeqBAIJGetArray(J, &a));
    std::vector<double> d(dof_);
    for (PetscInt node = 0; node < nb; ++node) {
      std::fill(d.begin(), d.end(), 0.0);
      for (PetscInt k = ia[node]; k < ia[node + 1]; ++k) {
        const bool in = offset(static_cast<int>(node), static_cast<int>(ja[k]), o, j, dj);
        const PetscScalar* blk = a + static_cast<std::size_t>(k) * dof_ * dof_;  // column-major
        for (int c2 = 0; c2 < dof_; ++c2)
          for (int c = 0; c < dof_; ++c) {
            const double avg = in ? stencil_[stencil_index(j, c, o, dj, c2)] : 0.0;
            d[c] = std::max(d[c], std::abs(blk[c2 * dof_ + c] - avg));
          }
      }
      const int jr = across_coordinate(static_cast<int>(node));
      for (int c = 0; c < dof_; ++c) {
        const double ref = row_max[jr * dof_ + c];
        dev[node] = std::max(dev[node], ref > 0 ? d[c] / ref : d[c]);
      }
    }
    CELLFSI_PETSC(MatSeqBAIJRestoreArray(J, &a));
    CELLFSI_PETSC(MatRestoreRowIJ(J, 0, PETSC_FALSE, PETSC_TRUE, &nb, &ia, &ja, &done));
    return dev;
  }
  for (PetscInt row = 0; row < rows; ++row) {
    PetscInt nc = 0;
    const PetscInt* ci = nullptr;
    const PetscScalar* v = nullptr;
    CELLFSI_PETSC(MatGetRow(J, row, &nc, &ci, &v));
    const int node = static_cast<int>(row / dof_), c = static_cast<int>(row % dof_);
    double d = 0;
    const int jr = across_coordinate(node);
    for (PetscInt k = 0; k < nc; ++k) {
      const bool in = offset(node, static_cast<int>(ci[k] / dof_), o, j, dj);
      const double avg = in ? stencil_[stencil_index(j, c, o, dj, static_cast<int>(ci[k] % dof_))] : 0.0;
      d = std::max(d, std::abs(v[k] - avg));
    }
    CELLFSI_PETSC(MatRestoreRow(J, row, &nc, &ci, &v));
    const double ref = row_max[jr * dof_ + c];
    dev[node] = std::max(dev[node], ref > 0 ? d / ref : d);
  }
  return dev;
}

}  // namespace cellfsi::fluid
