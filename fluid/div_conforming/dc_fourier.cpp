#include "fluid/div_conforming/dc_fourier.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <unordered_map>

#include "common/petsc_error.hpp"

namespace cellfsi::fluid::dc {

DcFourierSolver::DcFourierSolver(const DivConformingSpace& space) : space_(space) {
  if (space.dim() != 2 || !space.periodic(0))
    throw std::invalid_argument("DcFourierSolver: needs a 2D space periodic in x (got dim " +
                                std::to_string(space.dim()) + (space.periodic(0) ? "" : ", x not periodic") + ")");
  nx_ = space.n_elements(0);
  int off = 0;
  for (int c = 0; c <= 2; ++c) {
    if (space.n_basis(c, 0) != nx_) throw std::logic_error("DcFourierSolver: a periodic component without n_x functions");
    line_offset_.push_back(off);
    off += space.n_basis(c, 1);
  }
  n_line_ = off;
}

void DcFourierSolver::build(Mat A, bool pin_pressure) {
  const int n_comp = 3;
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
      const PetscInt row = space_.offset(c) + nx_ * j;
      PetscInt ncols;
      const PetscInt* cols;
      const PetscScalar* vals;
      CELLFSI_PETSC(MatGetRow(A, row, &ncols, &cols, &vals));
      for (PetscInt k = 0; k < ncols; ++k) {
        int i, line;
        decode(static_cast<int>(cols[k]), i, line);
        S[i](line_offset_[c] + j, line) += vals[k];
      }
      CELLFSI_PETSC(MatRestoreRow(A, row, &ncols, &cols, &vals));
    }
  // How far A is from the circulant matrix of S, row by row.
  deviation_ = 0;
  const int n = space_.n_dofs();
  for (int g = 0; g < n; ++g) {
    int i, line;
    decode(g, i, line);
    PetscInt ncols;
    const PetscInt* cols;
    const PetscScalar* vals;
    CELLFSI_PETSC(MatGetRow(A, g, &ncols, &cols, &vals));
    std::unordered_map<int, double> row;
    double row_max = 0;
    for (PetscInt k = 0; k < ncols; ++k) {
      row[static_cast<int>(cols[k])] += vals[k];
      row_max = std::max(row_max, std::abs(vals[k]));
    }
    CELLFSI_PETSC(MatRestoreRow(A, g, &ncols, &cols, &vals));
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
  // A_m = sum_s S_s e^{2 pi i m s / n}, factorised.
  lu_.clear();
  const double two_pi = 2 * std::numbers::pi;
  for (int m = 0; m < nx_; ++m) {
    Eigen::MatrixXcd Am = Eigen::MatrixXcd::Zero(n_line_, n_line_);
    for (int s = 0; s < nx_; ++s) {
      if (S[s].isZero(0.0)) continue;
      Am += S[s].cast<Complex>() * std::polar(1.0, two_pi * m * s / nx_);
    }
    pinned_ = pin_pressure;
    if (m == 0 && pin_pressure) {
      const int pin = line_offset_[2];
      Am.row(pin).setZero();
      Am(pin, pin) = 1.0;
    }
    lu_.emplace_back(Am);
  }
}

void DcFourierSolver::solve(const std::vector<double>& b, std::vector<double>& x) const {
  if (lu_.empty()) throw std::logic_error("DcFourierSolver::solve before build");
  const double two_pi = 2 * std::numbers::pi;
  // b_hat_m(line) = sum_i b(i, line) e^{-2 pi i m i / n}; x(i, line) = 1/n sum_m x_hat_m(line) e^{2 pi i m i / n}.
  std::vector<Complex> twiddle(nx_);
  for (int t = 0; t < nx_; ++t) twiddle[t] = std::polar(1.0, two_pi * t / nx_);
  auto index = [&](int c, int i, int j) { return space_.offset(c) + i + nx_ * j; };
  std::vector<Eigen::VectorXcd> xhat(nx_);
  for (int m = 0; m < nx_; ++m) {
    Eigen::VectorXcd bhat = Eigen::VectorXcd::Zero(n_line_);
    for (int c = 0; c < 3; ++c)
      for (int j = 0; j < space_.n_basis(c, 1); ++j) {
        Complex sum = 0;
        for (int i = 0; i < nx_; ++i) sum += b[index(c, i, j)] * std::conj(twiddle[(m * i) % nx_]);
        bhat[line_offset_[c] + j] = sum;
      }
    if (m == 0 && pinned_) bhat[line_offset_[2]] = 0.0;  // the pinned unit row fixes the pressure constant
    xhat[m] = lu_[m].solve(bhat);
  }
  x.assign(space_.n_dofs(), 0.0);
  for (int c = 0; c < 3; ++c)
    for (int j = 0; j < space_.n_basis(c, 1); ++j)
      for (int i = 0; i < nx_; ++i) {
        Complex sum = 0;
        for (int m = 0; m < nx_; ++m) sum += xhat[m][line_offset_[c] + j] * twiddle[(m * i) % nx_];
        x[index(c, i, j)] = sum.real() / nx_;
      }
}

}  // namespace cellfsi::fluid::dc
