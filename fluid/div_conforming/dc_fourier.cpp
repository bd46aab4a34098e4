#include "fluid/div_conforming/dc_fourier.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "common/petsc_error.hpp"

namespace cellfsi::fluid::dc {

DcFourierSolver::DcFourierSolver(const DivConformingSpace& space, MPI_Comm comm,
                                 std::vector<PetscInt> petsc_index)
    : space_(space), comm_(comm), petsc_index_(std::move(petsc_index)) {
  if (space.dim() != 2 || !space.periodic(0))
    throw std::invalid_argument("DcFourierSolver: needs a 2D space periodic in x (got dim " +
                                std::to_string(space.dim()) + (space.periodic(0) ? "" : ", x not periodic") +
                                ")");
  nx_ = space.n_elements(0);
  int off = 0;
  for (int c = 0; c <= 2; ++c) {
    if (space.n_basis(c, 0) != nx_)
      throw std::logic_error("DcFourierSolver: a periodic component without n_x functions");
    line_offset_.push_back(off);
    off += space.n_basis(c, 1);
  }
  n_line_ = off;
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
  for (int m = rank; m < nx_; m += size) modes_.push_back(m);
}

void DcFourierSolver::build(Mat A_in, bool pin_pressure) {
  const int n_comp = 3, n = space_.n_dofs();
  int rank = 0, size = 1;
  CELLFSI_PETSC(MPI_Comm_rank(comm_, &rank));
  CELLFSI_PETSC(MPI_Comm_size(comm_, &size));
  // A whole copy of the operator on every rank (the matrix itself on one rank).
  Mat A = A_in;
  Mat* copies = nullptr;
  if (size > 1) {
    IS all;
    CELLFSI_PETSC(ISCreateStride(PETSC_COMM_SELF, n, 0, 1, &all));
    CELLFSI_PETSC(MatCreateSubMatrices(A_in, 1, &all, &all, MAT_INITIAL_MATRIX, &copies));
    CELLFSI_PETSC(ISDestroy(&all));
    A = copies[0];
  }
  auto to_petsc = [&](int g) { return petsc_index_.empty() ? static_cast<PetscInt>(g) : petsc_index_[g]; };
  auto to_natural = [&](PetscInt p) {
    return natural_index_.empty() ? static_cast<int>(p) : static_cast<int>(natural_index_[p]);
  };
  // Decodes a natural index into (component, x index, line index).
  auto decode = [&](int g, int& i, int& line) {
    int c = n_comp - 1;
    while (g < space_.offset(c)) --c;
    const int local = g - space_.offset(c);
    i = local % nx_;
    line = line_offset_[c] + local / nx_;
  };
  // The stencil S_s (s: x shift, 0 .. n_x - 1) from the rows at x index 0.
  std::vector<Eigen::MatrixXd> S(nx_, Eigen::MatrixXd::Zero(n_line_, n_line_));
  for (int c = 0; c < n_comp; ++c)
    for (int j = 0; j < space_.n_basis(c, 1); ++j) {
      const PetscInt row = to_petsc(space_.offset(c) + nx_ * j);
      PetscInt ncols;
      const PetscInt* cols;
      const PetscScalar* vals;
      CELLFSI_PETSC(MatGetRow(A, row, &ncols, &cols, &vals));
      for (PetscInt k = 0; k < ncols; ++k) {
        int i, line;
        decode(to_natural(cols[k]), i, line);
        S[i](line_offset_[c] + j, line) += vals[k];
      }
      CELLFSI_PETSC(MatRestoreRow(A, row, &ncols, &cols, &vals));
    }
  // How far A is from the circulant matrix of S, row by row.
  deviation_ = 0;
  for (int g = rank; g < n; g += size) {
    int i, line;
    decode(g, i, line);
    PetscInt ncols;
    const PetscInt* cols;
    const PetscScalar* vals;
    CELLFSI_PETSC(MatGetRow(A, to_petsc(g), &ncols, &cols, &vals));
    std::unordered_map<int, double> row;
    double row_max = 0;
    for (PetscInt k = 0; k < ncols; ++k) {
      row[to_natural(cols[k])] += vals[k];
      row_max = std::max(row_max, std::abs(vals[k]));
    }
    CELLFSI_PETSC(MatRestoreRow(A, to_petsc(g), &ncols, &cols, &vals));
    double worst = 0;
    for (int s = 0; s < nx_; ++s)
      for (int c = 0; c < n_comp; ++c)
        for (int jj = 0; jj < space_.n_basis(c, 1); ++jj) {
          const double expected = S[s](line, line_offset_[c] + jj);
          const int col = space_.offset(c) + (i + s) % nx_ + nx_ * jj;
          const auto it = row.find(col);
          const double actual = it == row.end() ? 0.0 : it->second;
          worst = std::max(worst, std::abs(actual - expected));
          if (it != row.end()) row.erase(it);
        }
    for (const auto& [col, value] : row) worst = std::max(worst, std::abs(value));  // outside the stencil
    if (row_max > 0) deviation_ = std::max(deviation_, worst / row_max);
  }
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &deviation_, 1, MPI_DOUBLE, MPI_MAX, comm_));
  if (copies) CELLFSI_PETSC(MatDestroySubMatrices(1, &copies));
  // A_m = sum_s S_s e^{2 pi i m s / n}, factorised for this rank's m.
  lu_.clear();
  pinned_ = pin_pressure;
  const double two_pi = 2 * std::numbers::pi;
  for (int m : modes_) {
    Eigen::MatrixXcd Am = Eigen::MatrixXcd::Zero(n_line_, n_line_);
    for (int s = 0; s < nx_; ++s) {
      if (S[s].isZero(0.0)) continue;
      Am += S[s].cast<Complex>() * std::polar(1.0, two_pi * m * s / nx_);
    }
    if (m == 0 && pin_pressure) {
      const int pin = line_offset_[2];
      Am.row(pin).setZero();
      Am(pin, pin) = 1.0;
    }
    lu_.emplace_back(Am);
  }
  built_ = true;
}

void DcFourierSolver::solve(const std::vector<double>& b, std::vector<double>& x) const {
  if (!built_) throw std::logic_error("DcFourierSolver::solve before build");
  const double two_pi = 2 * std::numbers::pi;
  // b_hat_m(line) = sum_i b(i, line) e^{-2 pi i m i / n}; x(i, line) = 1/n sum_m x_hat_m(line) e^{2 pi i m i
  // / n}.
  std::vector<Complex> twiddle(nx_);
  for (int t = 0; t < nx_; ++t) twiddle[t] = std::polar(1.0, two_pi * t / nx_);
  auto index = [&](int c, int i, int j) { return space_.offset(c) + i + nx_ * j; };
  x.assign(space_.n_dofs(), 0.0);
  for (size_t k = 0; k < modes_.size(); ++k) {
    const int m = modes_[k];
    Eigen::VectorXcd bhat = Eigen::VectorXcd::Zero(n_line_);
    for (int c = 0; c < 3; ++c)
      for (int j = 0; j < space_.n_basis(c, 1); ++j) {
        Complex sum = 0;
        for (int i = 0; i < nx_; ++i) sum += b[index(c, i, j)] * std::conj(twiddle[(m * i) % nx_]);
        bhat[line_offset_[c] + j] = sum;
      }
    if (m == 0 && pinned_) bhat[line_offset_[2]] = 0.0;  // the pinned unit row fixes the pressure constant
    const Eigen::VectorXcd xhat = lu_[k].solve(bhat);
    // This mode's part of the inverse transform; the ranks' parts are summed below.
    for (int c = 0; c < 3; ++c)
      for (int j = 0; j < space_.n_basis(c, 1); ++j)
        for (int i = 0; i < nx_; ++i)
          x[index(c, i, j)] += (xhat[line_offset_[c] + j] * twiddle[(m * i) % nx_]).real() / nx_;
  }
  CELLFSI_PETSC(
      MPI_Allreduce(MPI_IN_PLACE, x.data(), static_cast<int>(x.size()), MPI_DOUBLE, MPI_SUM, comm_));
}

}  // namespace cellfsi::fluid::dc
