#include "fluid/div_conforming/dc_fourier.hpp"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "common/banded_lapack.hpp"
#include "common/petsc_error.hpp"
#include "common/row_scatter.hpp"

namespace cellfsi::fluid::dc {

// FFTW's plans for one line of one component (real to half spectrum and back): 2D, its n_x values,
// contiguous; 3D, its n_z x n_x values, n_x contiguous per z index and `stride` apart, to and from a
// contiguous half spectrum [n_z][n_x / 2 + 1]. Made once by build() and executed on every line (new-array
// execution; FFTW_UNALIGNED since lines start at any double).
struct DcFourierSolver::Plans {
  fftw_plan forward = nullptr, inverse = nullptr;
  Plans(int nx, int nz, int stride) {
    const int nh = nx / 2 + 1;
    std::vector<double> line(static_cast<std::size_t>(nz - 1) * stride + nx);
    std::vector<fftw_complex> half(static_cast<std::size_t>(nz) * nh);
    if (nz == 1) {
      forward = fftw_plan_dft_r2c_1d(nx, line.data(), half.data(), FFTW_ESTIMATE | FFTW_UNALIGNED);
      inverse = fftw_plan_dft_c2r_1d(nx, half.data(), line.data(), FFTW_ESTIMATE | FFTW_UNALIGNED);
    } else {
      const int n[2] = {nz, nx}, real_embed[2] = {nz, stride}, half_embed[2] = {nz, nh};
      forward = fftw_plan_many_dft_r2c(2, n, 1, line.data(), real_embed, 1, 0, half.data(), half_embed, 1, 0,
                                       FFTW_ESTIMATE | FFTW_UNALIGNED);
      inverse = fftw_plan_many_dft_c2r(2, n, 1, half.data(), half_embed, 1, 0, line.data(), real_embed, 1, 0,
                                       FFTW_ESTIMATE | FFTW_UNALIGNED);
    }
    if (!forward || !inverse)
      throw std::runtime_error("DcFourierSolver: FFTW made no plan for " + std::to_string(nz) + " x " +
                               std::to_string(nx));
  }
  ~Plans() {
    fftw_destroy_plan(forward);
    fftw_destroy_plan(inverse);
  }
  Plans(const Plans&) = delete;
  Plans& operator=(const Plans&) = delete;
};

DcFourierSolver::~DcFourierSolver() {
  VecScatterDestroy(&lines_scatter_);
  VecDestroy(&lines_values_);
}

DcFourierSolver::DcFourierSolver(const DivConformingSpace& space, MPI_Comm comm,
                                 std::vector<PetscInt> petsc_index)
    : space_(space), comm_(comm), petsc_index_(std::move(petsc_index)) {
  const int D = space.dim();
  if (space.is_mapped())
    throw std::invalid_argument("DcFourierSolver: a space on a curved patch is not translation-invariant");
  if (!space.periodic(0) || (D == 3 && !space.periodic(2)))
    throw std::invalid_argument(
        "DcFourierSolver: needs a space periodic in x (2D) or in x and z (3D); got dim " + std::to_string(D) +
        (space.periodic(0) ? "" : ", x not periodic") +
        (D == 3 && !space.periodic(2) ? ", z not periodic" : ""));
  nx_ = space.n_elements(0);
  nz_ = D == 3 ? space.n_elements(2) : 1;
  n_half_ = nx_ / 2 + 1;
  n_modes_ = nz_ * n_half_;
  int off = 0;
  for (int c = 0; c <= D; ++c) {
    if (space.n_basis(c, 0) != nx_ || (D == 3 && space.n_basis(c, 2) != nz_))
      throw std::logic_error("DcFourierSolver: a periodic component without one function per element");
    line_offset_.push_back(off);
    plane_stride_.push_back(nx_ * space.n_basis(c, 1));
    for (int j = 0; j < space.n_basis(c, 1); ++j) {
      line_component_.push_back(c);
      line_y_.push_back(j);
      line_first_.push_back(space.offset(c) + nx_ * j);
    }
    off += space.n_basis(c, 1);
  }
  n_line_ = off;
  // The banded order: by (y position, component); in y periodic the y position is folded so that the
  // neighbours across the period's end (j = 0 and n - 1) are neighbours in the order too.
  const bool periodic_y = space.periodic(1);
  auto y_position = [&](int c, int j) {
    const int ny = space.n_basis(c, 1);
    if (!periodic_y) return j;
    return j < (ny + 1) / 2 ? 2 * j : 2 * (ny - 1 - j) + 1;
  };
  std::vector<std::pair<std::pair<int, int>, int>> order(n_line_);
  for (int l = 0; l < n_line_; ++l)
    order[l] = {{y_position(line_component_[l], line_y_[l]), line_component_[l]}, l};
  std::sort(order.begin(), order.end());
  position_.assign(n_line_, 0);
  for (int p = 0; p < n_line_; ++p) position_[order[p].second] = p;
  if (!petsc_index_.empty()) {
    if (static_cast<int>(petsc_index_.size()) != space.n_dofs())
      throw std::invalid_argument("DcFourierSolver: petsc_index must have n_dofs() entries");
    natural_index_.assign(petsc_index_.size(), -1);
    for (size_t g = 0; g < petsc_index_.size(); ++g)
      natural_index_[petsc_index_[g]] = static_cast<PetscInt>(g);
  }
  int rank = 0, size = 1;
  CELLFSI_PETSC(MPI_Comm_rank(comm_, &rank));
  CELLFSI_PETSC(MPI_Comm_size(comm_, &size));
  for (int m = rank; m < n_modes_; m += size) modes_.push_back(m);
  comm_size_ = size;
}

void DcFourierSolver::build(Mat A, bool pin_pressure) {
  built_ = false;
  const int n = space_.n_dofs();
  auto to_petsc = [&](int g) { return petsc_index_.empty() ? static_cast<PetscInt>(g) : petsc_index_[g]; };
  auto to_natural = [&](PetscInt p) {
    return natural_index_.empty() ? static_cast<int>(p) : static_cast<int>(natural_index_[p]);
  };
  const int D = space_.dim();
  // Decodes a natural index into (component, x index, z index, line index).
  auto decode = [&](int g, int& c, int& i, int& l, int& line) {
    c = D;
    while (g < space_.offset(c)) --c;
    const int local = g - space_.offset(c), ny = space_.n_basis(c, 1);
    i = local % nx_;
    line = line_offset_[c] + (local / nx_) % ny;
    l = local / (nx_ * ny);
  };
  auto natural = [&](int line, int i, int l) {
    return line_first_[line] + i + plane_stride_[line_component_[line]] * l;
  };

  // 1. The stencil from the rows at x (and z) index 0, copied to every rank (sorted rows, as
  // MatCreateSubMatrices wants them; all columns, so that the copy keeps the matrix's column numbering).
  std::vector<std::pair<PetscInt, int>> stencil_rows(n_line_);  // (PETSc row, line)
  for (int l = 0; l < n_line_; ++l) stencil_rows[l] = {to_petsc(line_first_[l]), l};
  std::sort(stencil_rows.begin(), stencil_rows.end());
  std::vector<PetscInt> rows(n_line_);
  for (int q = 0; q < n_line_; ++q) rows[q] = stencil_rows[q].first;
  IS row_is, col_is;
  Mat* sub = nullptr;
  CELLFSI_PETSC(ISCreateGeneral(PETSC_COMM_SELF, n_line_, rows.data(), PETSC_COPY_VALUES, &row_is));
  CELLFSI_PETSC(ISCreateStride(PETSC_COMM_SELF, n, 0, 1, &col_is));
  CELLFSI_PETSC(MatCreateSubMatrices(A, 1, &row_is, &col_is, MAT_INITIAL_MATRIX, &sub));
  CELLFSI_PETSC(ISDestroy(&row_is));
  CELLFSI_PETSC(ISDestroy(&col_is));
  std::vector<StencilEntry> stencil;
  for (int q = 0; q < n_line_; ++q) {
    const int row_line = stencil_rows[q].second;
    PetscInt ncols;
    const PetscInt* cols;
    const PetscScalar* vals;
    CELLFSI_PETSC(MatGetRow(sub[0], q, &ncols, &cols, &vals));
    for (PetscInt k = 0; k < ncols; ++k) {
      int c, i, l, line;
      decode(to_natural(cols[k]), c, i, l, line);
      stencil.push_back({row_line, line, i, l, vals[k]});
    }
    CELLFSI_PETSC(MatRestoreRow(sub[0], q, &ncols, &cols, &vals));
  }
  CELLFSI_PETSC(MatDestroySubMatrices(1, &sub));
  // Entries sorted by (row, column line, shift), duplicates (a short period folding shifts) summed, zeros
  // dropped; row_start: each row line's first entry.
  std::sort(stencil.begin(), stencil.end(), [](const StencilEntry& a, const StencilEntry& b) {
    return std::tie(a.row, a.col, a.shift_z, a.shift) < std::tie(b.row, b.col, b.shift_z, b.shift);
  });
  {
    std::vector<StencilEntry> merged;
    for (const StencilEntry& e : stencil)
      if (!merged.empty() && merged.back().row == e.row && merged.back().col == e.col &&
          merged.back().shift == e.shift && merged.back().shift_z == e.shift_z)
        merged.back().value += e.value;
      else
        merged.push_back(e);
    stencil.clear();
    for (const StencilEntry& e : merged)
      if (e.value != 0.0) stencil.push_back(e);
  }
  std::vector<int> row_start(n_line_ + 1, 0);
  for (const StencilEntry& e : stencil) ++row_start[e.row + 1];
  for (int l = 0; l < n_line_; ++l) row_start[l + 1] += row_start[l];

  // 2. How far A is from the circulant matrix of the stencil: each rank its own rows, row by row (the
  // differences of the row's entries and the stencil's, both by natural column). A row without entries is
  // one A does not hold (DivConformingFluid::bulk_stencil_tangent holds a few positions' rows only); every
  // row of a whole operator has its pattern.
  deviation_ = 0;
  PetscInt row_begin = 0, row_end = 0;
  CELLFSI_PETSC(MatGetOwnershipRange(A, &row_begin, &row_end));
  std::vector<std::pair<int, double>> diff;
  for (PetscInt p = row_begin; p < row_end; ++p) {
    int c, i, l, line;
    decode(to_natural(p), c, i, l, line);
    PetscInt ncols;
    const PetscInt* cols;
    const PetscScalar* vals;
    CELLFSI_PETSC(MatGetRow(A, p, &ncols, &cols, &vals));
    if (ncols == 0) {
      CELLFSI_PETSC(MatRestoreRow(A, p, &ncols, &cols, &vals));
      continue;
    }
    diff.clear();
    double row_max = 0;
    for (PetscInt k = 0; k < ncols; ++k) {
      diff.emplace_back(to_natural(cols[k]), vals[k]);
      row_max = std::max(row_max, std::abs(vals[k]));
    }
    CELLFSI_PETSC(MatRestoreRow(A, p, &ncols, &cols, &vals));
    for (int e = row_start[line]; e < row_start[line + 1]; ++e) {
      const StencilEntry& s = stencil[e];
      diff.emplace_back(natural(s.col, (i + s.shift) % nx_, (l + s.shift_z) % nz_), -s.value);
    }
    std::sort(diff.begin(), diff.end());
    double worst = 0;
    for (size_t a = 0; a < diff.size();) {
      double sum = 0;
      const int col = diff[a].first;
      for (; a < diff.size() && diff[a].first == col; ++a) sum += diff[a].second;
      worst = std::max(worst, std::abs(sum));
    }
    if (row_max > 0) deviation_ = std::max(deviation_, worst / row_max);
  }
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &deviation_, 1, MPI_DOUBLE, MPI_MAX, comm_));

  // 3. The half-bandwidths in the banded order, from the stencil's nonzeros.
  kl_ = ku_ = 0;
  for (const StencilEntry& e : stencil) {
    kl_ = std::max(kl_, position_[e.row] - position_[e.col]);
    ku_ = std::max(ku_, position_[e.col] - position_[e.row]);
  }
  ldab_ = 2 * kl_ + ku_ + 1;  // zgbtrf: kl rows of fill above the ku + kl + 1 of the band

  // 4. A_mq = sum_s S_s e^{2 pi i (m s_x / n_x + q s_z / n_z)} in LAPACK's band storage (A(r, l) at
  // ab[kl + ku + r - l + l ldab]), factorised for this rank's wave vectors (index q n_half + m).
  pinned_ = pin_pressure;
  const std::size_t slice = static_cast<std::size_t>(ldab_) * n_line_;
  ab_.assign(modes_.size() * slice, Complex(0.0));
  ipiv_.assign(modes_.size() * n_line_, 0);
  inverse_diagonal_.assign(modes_.size() * n_line_, Complex(0.0));
  std::vector<Complex> phase(nx_), phase_z(nz_);
  for (int t = 0; t < nx_; ++t) phase[t] = std::polar(1.0, 2 * std::numbers::pi * t / nx_);
  for (int t = 0; t < nz_; ++t) phase_z[t] = std::polar(1.0, 2 * std::numbers::pi * t / nz_);
  PetscBLASInt m_blas = 0, kl = 0, ku = 0, ldab = 0;
  CELLFSI_PETSC(PetscBLASIntCast(n_line_, &m_blas));
  CELLFSI_PETSC(PetscBLASIntCast(kl_, &kl));
  CELLFSI_PETSC(PetscBLASIntCast(ku_, &ku));
  CELLFSI_PETSC(PetscBLASIntCast(ldab_, &ldab));
  const int pin = position_[line_offset_[D]];  // the first pressure unknown (x, y, z index 0)
  int singular = -1, singular_info = 0;        // a wave number whose A_m is singular, and zgbtrf's info
  for (size_t k = 0; k < modes_.size(); ++k) {
    const int mode = modes_[k], m = mode % n_half_, q = mode / n_half_;
    Complex* ab = &ab_[k * slice];
    for (const StencilEntry& e : stencil) {
      const int r = position_[e.row], l = position_[e.col];
      ab[(kl_ + ku_ + r - l) + static_cast<std::size_t>(l) * ldab_] +=
          e.value * phase[(static_cast<long>(m) * e.shift) % nx_] *
          phase_z[(static_cast<long>(q) * e.shift_z) % nz_];
    }
    if (mode == 0 && pin_pressure) {  // a unit row for the pin
      for (int l = std::max(0, pin - kl_); l <= std::min(n_line_ - 1, pin + ku_); ++l)
        ab[(kl_ + ku_ + pin - l) + static_cast<std::size_t>(l) * ldab_] = 0.0;
      ab[(kl_ + ku_) + static_cast<std::size_t>(pin) * ldab_] = 1.0;
    }
    PetscBLASInt info = 0;
    zgbtrf_(&m_blas, &m_blas, &kl, &ku, ab, &ldab, &ipiv_[k * n_line_], &info);
    for (int j = 0; j < n_line_ && info == 0; ++j)  // U's diagonal, inverted once for the substitutions
      inverse_diagonal_[k * n_line_ + j] = 1.0 / ab[(kl_ + ku_) + static_cast<std::size_t>(j) * ldab_];
    if (info < 0)
      throw std::logic_error("DcFourierSolver: zgbtrf rejected argument " + std::to_string(-info));
    if (info > 0 && singular < 0) {
      singular = mode;
      singular_info = static_cast<int>(info);
    }
  }
  int worst[2] = {singular, singular_info};
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, worst, 1, MPI_2INT, MPI_MAXLOC, comm_));
  if (worst[0] >= 0)
    throw std::runtime_error(
        "DcFourierSolver: the system of wave vector (" + std::to_string(worst[0] % n_half_) + ", " +
        std::to_string(worst[0] / n_half_) + ")" + " is singular (LAPACK zgbtrf: zero pivot in column " +
        std::to_string(worst[1]) + " of " + std::to_string(n_line_) + ")" +
        (worst[0] == 0 && !pin_pressure
             ? "; wave 0 of a box without outflow has the constant pressure as null vector: build with "
               "pin_pressure = true"
             : "; is the operator invertible?"));
  if (plans_.empty())
    for (int c = 0; c <= D; ++c) plans_.push_back(std::make_unique<Plans>(nx_, nz_, plane_stride_[c]));
  // 5. The stencil by (row line, column line) pair for multiply(), its shifts as signed offsets.
  auto signed_offset = [](int shift, int n) { return shift <= n / 2 ? shift : shift - n; };
  halo_ = halo_z_ = 0;
  for (const StencilEntry& e : stencil) {
    halo_ = std::max(halo_, std::abs(signed_offset(e.shift, nx_)));
    halo_z_ = std::max(halo_z_, std::abs(signed_offset(e.shift_z, nz_)));
  }
  const int width = 2 * halo_ + 1, block = (2 * halo_z_ + 1) * width;
  pair_row_.clear();
  pair_col_.clear();
  pair_taps_.clear();
  for (const StencilEntry& e : stencil) {  // sorted by (row, column line, z shift, x shift)
    if (pair_row_.empty() || pair_row_.back() != e.row || pair_col_.back() != e.col) {
      pair_row_.push_back(e.row);
      pair_col_.push_back(e.col);
      pair_taps_.resize(pair_taps_.size() + block, 0.0);
    }
    pair_taps_[pair_taps_.size() - block + (signed_offset(e.shift_z, nz_) + halo_z_) * width +
               signed_offset(e.shift, nx_) + halo_] += e.value;
  }
  // The runs (line, l) that hold a row of this rank's (A's ownership range), for multiply(owned_only).
  PetscInt r0 = 0, r1 = 0;
  CELLFSI_PETSC(MatGetOwnershipRange(A, &r0, &r1));
  owned_runs_.assign(static_cast<std::size_t>(n_line_) * nz_, 0);
  for (int line = 0; line < n_line_; ++line)
    for (int l = 0; l < nz_; ++l)
      for (int i = 0; i < nx_; ++i) {
        const PetscInt r = to_petsc(line_first_[line] + plane_stride_[line_component_[line]] * l + i);
        if (r >= r0 && r < r1) {
          owned_runs_[static_cast<std::size_t>(line) * nz_ + l] = 1;
          break;
        }
      }
  built_ = true;
}

namespace {

/// The pairs' products: for each pair (r, c), z index l and z offset tz, y_r[l][i] += sum_t w[tz][t]
/// x_pad_c[l + tz][i + t] (x_pad: line c with its halos, so that t = 0 is the x offset -halo and tz = 0 the z
/// offset -halo_z), W x taps known at compile time (W = 0: any width) so that the loop over i vectorises.
struct PairProduct {
  int nx, nz, wz, padded_x, padded_line;  // run length, runs, z taps, padded run and line lengths
  std::size_t n_pairs;
  const int *rows, *cols;
  const double *taps, *padded;
  const int *first, *row_stride;  // per line: its first unknown and its z stride
  const char* runs;               // per (line, l): whether to compute it (null: every run)
};

template <int W>
void multiply_pairs(const PairProduct& p, int width, double* y) {
  const int wx = W > 0 ? W : width;
  double terms = 0;  // (-log_view's counts: the multiply-adds, nx per tap of a run)
  for (std::size_t g = 0; g < p.n_pairs; ++g) {
    const double* wg = p.taps + g * static_cast<std::size_t>(p.wz) * wx;
    const double* xc = p.padded + static_cast<std::size_t>(p.cols[g]) * p.padded_line;
    for (int l = 0; l < p.nz; ++l) {
      if (p.runs && !p.runs[static_cast<std::size_t>(p.rows[g]) * p.nz + l]) continue;
      double* __restrict yr = y + p.first[p.rows[g]] + static_cast<std::size_t>(p.row_stride[p.rows[g]]) * l;
      for (int tz = 0; tz < p.wz; ++tz) {
        const double* w = wg + tz * wx;
        const double* __restrict xl = xc + static_cast<std::size_t>(l + tz) * p.padded_x;
        if constexpr (W > 0) {
          double wl[W];
          bool zero = true;
          for (int t = 0; t < W; ++t) {
            wl[t] = w[t];
            zero = zero && wl[t] == 0.0;
          }
          if (zero) continue;  // (3D: the corners of the z x x block)
          terms += W;
          for (int i = 0; i < p.nx; ++i) {
            double acc = 0;
            for (int t = 0; t < W; ++t) acc += wl[t] * xl[i + t];
            yr[i] += acc;
          }
        } else {
          for (int t = 0; t < wx; ++t)
            if (w[t] != 0.0) {
              terms += 1;
              for (int i = 0; i < p.nx; ++i) yr[i] += w[t] * xl[i + t];
            }
        }
      }
    }
  }
  CELLFSI_PETSC(PetscLogFlops(2.0 * terms * p.nx));
}

}  // namespace

void DcFourierSolver::multiply(const std::vector<double>& x, std::vector<double>& y, bool owned_only) const {
  if (!built_) throw std::logic_error("DcFourierSolver::multiply before build");
  if (static_cast<int>(x.size()) != space_.n_dofs())
    throw std::invalid_argument("DcFourierSolver::multiply: the vector has " + std::to_string(x.size()) +
                                " entries, not n_dofs() = " + std::to_string(space_.n_dofs()));
  const int n = nx_, h = halo_, hz = halo_z_, Lx = n + 2 * h, Lz = nz_ + 2 * hz, W = 2 * h + 1;
  const std::size_t line_length = static_cast<std::size_t>(Lx) * Lz;
  // Each line of x with its periodic halos: padded[line][j_z][j_x] = x_line[(j_z - hz) mod n_z][(j_x - h) mod
  // n].
  padded_.resize(static_cast<std::size_t>(n_line_) * line_length);
  std::vector<int> stride(n_line_);
  for (int line = 0; line < n_line_; ++line) {
    stride[line] = plane_stride_[line_component_[line]];
    for (int jz = 0; jz < Lz; ++jz) {
      const double* xl =
          &x[line_first_[line] + static_cast<std::size_t>(stride[line]) * (((jz - hz) % nz_ + nz_) % nz_)];
      double* p = &padded_[line * line_length + static_cast<std::size_t>(jz) * Lx];
      std::copy(xl, xl + n, p + h);
      for (int j = 0; j < h; ++j) {
        p[j] = xl[((j - h) % n + n) % n];
        p[h + n + j] = xl[j % n];
      }
    }
  }
  // (-log_view's counts: every line padded on every rank, which does not divide; 3 operations a value)
  CELLFSI_PETSC(PetscLogFlops(3.0 * static_cast<double>(padded_.size())));
  y.assign(x.size(), 0.0);
  const PairProduct pp{n,
                       nz_,
                       2 * hz + 1,
                       Lx,
                       static_cast<int>(line_length),
                       pair_row_.size(),
                       pair_row_.data(),
                       pair_col_.data(),
                       pair_taps_.data(),
                       padded_.data(),
                       line_first_.data(),
                       stride.data(),
                       owned_only ? owned_runs_.data() : nullptr};
  switch (W) {  // k' = 1, 2, 3: halo k' + 1
    case 5:
      multiply_pairs<5>(pp, W, y.data());
      break;
    case 7:
      multiply_pairs<7>(pp, W, y.data());
      break;
    case 9:
      multiply_pairs<9>(pp, W, y.data());
      break;
    default:
      multiply_pairs<0>(pp, W, y.data());
  }
}

template <class PerMode>
void DcFourierSolver::transform(const std::vector<double>& b, std::vector<double>& x, PerMode&& f,
                                bool whole) const {
  if (!built_) throw std::logic_error("DcFourierSolver::solve before build");
  if (static_cast<int>(b.size()) != space_.n_dofs())
    throw std::invalid_argument("DcFourierSolver: the vector has " + std::to_string(b.size()) +
                                " entries, not n_dofs() = " + std::to_string(space_.n_dofs()));
  int rank = 0, size = 1;
  CELLFSI_PETSC(MPI_Comm_rank(comm_, &rank));
  CELLFSI_PETSC(MPI_Comm_size(comm_, &size));
  // Each rank transforms its own run of lines (both ways), the wave vectors' values go to the ranks that
  // solve them and come back (two MPI_Alltoallv), and the lines are gathered into x on every rank. Before,
  // every rank transformed every line and the half spectra were summed (one MPI_Allreduce): at 64^3 the
  // transforms were the part of a 3D step's linear solves that did not divide (bench/scaling_counts_3d.py).
  const int l0 = line_begin(rank), l1 = line_begin(rank + 1);
  // 1. Each of this rank's lines' half spectrum, b_hat_mq = sum_il b_il e^{-2 pi i (m i / n_x + q l /
  // n_z)}, m = 0 .. n_x/2, by banded position and wave vector: spectrum[p * n_modes + q * n_half + m].
  const std::size_t nm = n_modes_;
  // (A buffer kept between solves: every entry read is written by the forward transforms or the exchange. A
  // new one per solve, 9 MB at 64^3, came back from the kernel as fresh pages to fault in and clear: 5 % of
  // a 3D step, perf.)
  std::vector<Complex>& spectrum = spectrum_;
  spectrum.resize(nm * n_line_);
  auto half = [&](int line) { return reinterpret_cast<fftw_complex*>(&spectrum[position_[line] * nm]); };
  auto plan = [&](int line) -> const Plans& { return *plans_[line_component_[line]]; };
  for (int l = l0; l < l1; ++l)  // FFTW's r2c leaves its input as it is (out of place)
    fftw_execute_dft_r2c(plan(l).forward, const_cast<double*>(&b[line_first_[l]]), half(l));
  // (-log_view's counts: a real transform of N points as 2.5 N log2 N operations, FFTW's own estimate; both
  // ways, and the inverse's scaling)
  const double n_points = static_cast<double>(nx_) * nz_;
  CELLFSI_PETSC(PetscLogFlops((l1 - l0) * (5.0 * n_points * std::log2(n_points) + n_points)));
  // 2. This rank's wave vectors, each result in place of its right-hand side.
  std::vector<Complex> rhs(n_line_);
  const auto n_modes_of = [&](int r) { return r < n_modes_ ? (n_modes_ - 1 - r) / size + 1 : 0; };
  if (size == 1) {
    for (size_t k = 0; k < modes_.size(); ++k) {
      const int m = modes_[k];
      for (int p = 0; p < n_line_; ++p) rhs[p] = spectrum[p * nm + m];
      f(k, m, rhs);
      for (int p = 0; p < n_line_; ++p) spectrum[p * nm + m] = rhs[p];
    }
  } else {
    // Rank r's lines [line_begin(r), line_begin(r + 1)) and wave vectors r, r + size, ...: a message from r
    // to s holds r's lines' values at s's wave vectors, line by line.
    std::vector<int>& send_counts = exchange_counts_[0];
    std::vector<int>& send_displs = exchange_counts_[1];
    std::vector<int>& recv_counts = exchange_counts_[2];
    std::vector<int>& recv_displs = exchange_counts_[3];
    for (auto* v : {&send_counts, &send_displs, &recv_counts, &recv_displs}) v->assign(size, 0);
    for (int r = 0; r < size; ++r) {
      send_counts[r] = 2 * (l1 - l0) * n_modes_of(r);
      recv_counts[r] = 2 * (line_begin(r + 1) - line_begin(r)) * n_modes_of(rank);
    }
    for (int r = 1; r < size; ++r) {
      send_displs[r] = send_displs[r - 1] + send_counts[r - 1];
      recv_displs[r] = recv_displs[r - 1] + recv_counts[r - 1];
    }
    std::vector<Complex>& out = exchange_send_;
    std::vector<Complex>& in = exchange_recv_;
    out.resize(static_cast<std::size_t>(send_displs[size - 1] + send_counts[size - 1]) / 2);
    in.resize(static_cast<std::size_t>(recv_displs[size - 1] + recv_counts[size - 1]) / 2);
    std::size_t o = 0;
    for (int r = 0; r < size; ++r)
      for (int l = l0; l < l1; ++l)
        for (int m = r; m < n_modes_; m += size) out[o++] = spectrum[position_[l] * nm + m];
    CELLFSI_PETSC(MPI_Alltoallv(out.data(), send_counts.data(), send_displs.data(), MPI_DOUBLE, in.data(),
                                recv_counts.data(), recv_displs.data(), MPI_DOUBLE, comm_));
    // The values of this rank's wave vector k: in[base[l] + k], base[l] = (recv_displs[r] / 2) + (l -
    // line_begin(r)) n_mine for line l of rank r.
    const auto n_mine = modes_.size();
    std::vector<std::size_t>& base = exchange_base_;
    base.resize(n_line_);
    for (int r = 0; r < size; ++r)
      for (int l = line_begin(r); l < line_begin(r + 1); ++l)
        base[l] = static_cast<std::size_t>(recv_displs[r] / 2) +
                  static_cast<std::size_t>(l - line_begin(r)) * n_mine;
    const auto at = [&](int l, std::size_t k) -> Complex& { return in[base[l] + k]; };
    for (size_t k = 0; k < n_mine; ++k) {
      for (int l = 0; l < n_line_; ++l) rhs[position_[l]] = at(l, k);
      f(k, modes_[k], rhs);
      for (int l = 0; l < n_line_; ++l) at(l, k) = rhs[position_[l]];
    }
    // Back: the same messages the other way.
    CELLFSI_PETSC(MPI_Alltoallv(in.data(), recv_counts.data(), recv_displs.data(), MPI_DOUBLE, out.data(),
                                send_counts.data(), send_displs.data(), MPI_DOUBLE, comm_));
    o = 0;
    for (int r = 0; r < size; ++r)
      for (int l = l0; l < l1; ++l)
        for (int m = r; m < n_modes_; m += size) spectrum[position_[l] * nm + m] = out[o++];
  }
  // 3. This rank's lines' inverse transforms (scaled by 1/(n_x n_z); from the half spectrum, the other half
  // being its conjugate since x is real), then every rank's lines into x on every rank.
  x.resize(space_.n_dofs());
  const double scale = 1.0 / (static_cast<double>(nx_) * nz_);  // FFTW's inverse is unscaled
  for (int l = l0; l < l1; ++l) {
    double* line = &x[line_first_[l]];
    fftw_execute_dft_c2r(plan(l).inverse, half(l),
                         line);  // (overwrites the spectrum's line, not needed again)
    const int stride = plane_stride_[line_component_[l]];
    for (int z = 0; z < nz_; ++z)
      for (int i = 0; i < nx_; ++i) line[static_cast<std::size_t>(stride) * z + i] *= scale;
  }
  if (size == 1 || !whole) return;
  std::vector<int>& counts = exchange_counts_[0];
  std::vector<int>& displs = exchange_counts_[1];
  const int per_line = nx_ * nz_;
  for (int r = 0; r < size; ++r) {
    counts[r] = (line_begin(r + 1) - line_begin(r)) * per_line;
    displs[r] = line_begin(r) * per_line;
  }
  std::vector<double>& lines = exchange_lines_;
  lines.resize(static_cast<std::size_t>(n_line_) * per_line);
  const auto each_value = [&](int l, auto&& visit) {
    const int stride = plane_stride_[line_component_[l]];
    std::size_t v = static_cast<std::size_t>(l) * per_line;
    for (int z = 0; z < nz_; ++z)
      for (int i = 0; i < nx_; ++i)
        visit(lines[v++], x[line_first_[l] + static_cast<std::size_t>(stride) * z + i]);
  };
  for (int l = l0; l < l1; ++l) each_value(l, [](double& packed, double& value) { packed = value; });
  CELLFSI_PETSC(MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, lines.data(), counts.data(), displs.data(),
                               MPI_DOUBLE, comm_));
  for (int l = 0; l < n_line_; ++l)
    if (l < l0 || l >= l1) each_value(l, [](double& packed, double& value) { value = packed; });
  // (-log_view's counts: every rank unpacks every other rank's lines, which does not divide; 3 operations a
  // value, as the fluid's gather weighs its copies)
  CELLFSI_PETSC(PetscLogFlops(3.0 * (n_line_ - (l1 - l0)) * per_line));
}

void DcFourierSolver::solve(const std::vector<double>& b, std::vector<double>& x) const {
  solve_lines(b, x, true);
}

void DcFourierSolver::solve_lines(const std::vector<double>& b, std::vector<double>& x, bool whole) const {
  const std::size_t slice = static_cast<std::size_t>(ldab_) * n_line_;
  const int pin = position_[line_offset_[space_.dim()]];
  transform(
      b, x,
      [&](size_t k, int m, std::vector<Complex>& rhs) {
        if (m == 0 && pinned_) rhs[pin] = 0.0;  // the pinned unit row fixes the constant
        banded_substitution(&ab_[k * slice], &ipiv_[k * n_line_], &inverse_diagonal_[k * n_line_],
                            rhs.data());
      },
      whole);
}

template <class Visit>
void DcFourierSolver::for_each_line_unknown(Visit&& visit) const {
  int rank = 0;
  CELLFSI_PETSC(MPI_Comm_rank(comm_, &rank));
  std::size_t k = 0;
  for (int l = line_begin(rank); l < line_begin(rank + 1); ++l) {
    const int stride = plane_stride_[line_component_[l]];
    for (int z = 0; z < nz_; ++z)
      for (int i = 0; i < nx_; ++i) visit(k++, line_first_[l] + stride * z + i);
  }
}

void DcFourierSolver::solve(Vec b, Vec x) const {
  if (!built_) throw std::logic_error("DcFourierSolver::solve before build");
  if (!lines_scatter_) {
    std::vector<PetscInt> rows;
    for_each_line_unknown([&](std::size_t, int g) {
      rows.push_back(petsc_index_.empty() ? static_cast<PetscInt>(g) : petsc_index_[g]);
    });
    // (the lines hold every unknown once: n_x n_z values each)
    if (static_cast<long long>(n_line_) * nx_ * nz_ != space_.n_dofs())
      throw std::logic_error("DcFourierSolver: the lines do not hold every unknown once");
    lines_scatter_ = make_row_scatter(b, rows, lines_values_);
    lines_b_.assign(space_.n_dofs(), 0.0);
  }
  CELLFSI_PETSC(VecScatterBegin(lines_scatter_, b, lines_values_, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(VecScatterEnd(lines_scatter_, b, lines_values_, INSERT_VALUES, SCATTER_FORWARD));
  const PetscScalar* in = nullptr;
  CELLFSI_PETSC(VecGetArrayRead(lines_values_, &in));
  for_each_line_unknown([&](std::size_t k, int g) { lines_b_[g] = in[k]; });
  CELLFSI_PETSC(VecRestoreArrayRead(lines_values_, &in));
  solve_lines(lines_b_, lines_x_, false);  // (this rank's lines of lines_x_ only)
  PetscScalar* out = nullptr;
  CELLFSI_PETSC(VecGetArray(lines_values_, &out));
  std::size_t n = 0;
  for_each_line_unknown([&](std::size_t k, int g) { out[k] = lines_x_[g], n = k + 1; });
  CELLFSI_PETSC(VecRestoreArray(lines_values_, &out));
  CELLFSI_PETSC(VecScatterBegin(lines_scatter_, lines_values_, x, INSERT_VALUES, SCATTER_REVERSE));
  CELLFSI_PETSC(VecScatterEnd(lines_scatter_, lines_values_, x, INSERT_VALUES, SCATTER_REVERSE));
  // (-log_view's counts: the two copies of this rank's values, 3 operations a value as the fluid's gather)
  CELLFSI_PETSC(PetscLogFlops(6.0 * n));
}

void DcFourierSolver::banded_substitution(const Complex* ab, const PetscBLASInt* ipiv,
                                          const Complex* inv_diag, Complex* rhs) const {
  // zgbtrs('N') for one right-hand side, written out: LAPACK's calls one BLAS level-2 routine per column for
  // a band of a few dozen entries, and std::complex's operator* checks for infinities (GCC's __muldc3); here
  // the products are written in real arithmetic and the diagonal is inverted once at build (bench
  // dc_fourier_solve, 256 x 128: 4.2 ms per solve with zgbtrs). The factors are zgbtrf's: L's multipliers
  // below the diagonal row kl + ku of each column, its row interchanges in ipiv (1-based); U in the rows
  // above, kl + ku superdiagonals.
  const int n = n_line_, d = kl_ + ku_;
  double* r = reinterpret_cast<double*>(rhs);  // std::complex<double> is an array of two doubles
  // (-log_view's counts: 8 per complex multiply-add of the band, 6 per diagonal; the zero skips not counted)
  CELLFSI_PETSC(PetscLogFlops(n * (8.0 * (kl_ + d) + 6.0)));
  const double* a = reinterpret_cast<const double*>(ab);
  // L: forward elimination with the interchanges.
  for (int j = 0; j + 1 < n; ++j) {
    const int l = static_cast<int>(ipiv[j]) - 1;
    if (l != j) {
      std::swap(r[2 * l], r[2 * j]);
      std::swap(r[2 * l + 1], r[2 * j + 1]);
    }
    const double br = r[2 * j], bi = r[2 * j + 1];
    if (br == 0.0 && bi == 0.0) continue;
    const int lm = std::min(kl_, n - 1 - j);
    const double* col = a + 2 * (static_cast<std::size_t>(j) * ldab_ + d + 1);
    double* t = r + 2 * (j + 1);
    for (int i = 0; i < lm; ++i) {
      t[2 * i] -= br * col[2 * i] - bi * col[2 * i + 1];
      t[2 * i + 1] -= br * col[2 * i + 1] + bi * col[2 * i];
    }
  }
  // U: back substitution, column by column.
  const double* q = reinterpret_cast<const double*>(inv_diag);
  for (int j = n - 1; j >= 0; --j) {
    const double br = r[2 * j], bi = r[2 * j + 1];
    if (br == 0.0 && bi == 0.0) continue;
    const double xr = br * q[2 * j] - bi * q[2 * j + 1], xi = br * q[2 * j + 1] + bi * q[2 * j];
    r[2 * j] = xr;
    r[2 * j + 1] = xi;
    const int lm = std::min(d, j);
    const double* col = a + 2 * (static_cast<std::size_t>(j) * ldab_ + d - lm);  // rows j - lm .. j - 1
    double* t = r + 2 * (j - lm);
    for (int i = 0; i < lm; ++i) {
      t[2 * i] -= xr * col[2 * i] - xi * col[2 * i + 1];
      t[2 * i + 1] -= xr * col[2 * i + 1] + xi * col[2 * i];
    }
  }
}

}  // namespace cellfsi::fluid::dc
