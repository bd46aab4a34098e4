#include "fluid/div_conforming/dc_fluid.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>

#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkStructuredGrid.h>
#include <vtkXMLStructuredGridWriter.h>

#include <Eigen/Sparse>

#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <petscblaslapack.h>

#include "common/petsc_error.hpp"
#include "common/row_scatter.hpp"
#include "fluid/div_conforming/dc_kernel.hpp"
#include "fluid/div_conforming/dc_sum_factorization.hpp"
#include "geometry/inversion.hpp"
#include "geometry/patch_vtk.hpp"

namespace cellfsi::fluid::dc {

namespace {

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("DcFluidOptions: " + what);
}

double get_real(const char* name, double value) {
  PetscReal v = value;
  PetscBool set = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsGetReal(nullptr, nullptr, name, &v, &set));
  return set ? v : value;
}

/// Adds the point's contribution to the element residual Fe, from the kernel's output. Local numbering: the
/// functions of component 0, then 1, ..., then pressure (eb.comp[c].n each).
void add_point_residual(const ElementBasis& eb, int q, int dim, double w, const PointResidual& r,
                        std::vector<double>& Fe) {
  int off = 0;
  for (int i = 0; i < dim; ++i) {
    const ComponentBasis& cb = eb.comp[i];
    for (int a = 0; a < cb.n; ++a) {
      const size_t k = static_cast<size_t>(q) * cb.n + a;
      double s = cb.value[k] * r.r0[i];
      for (int j = 0; j < dim; ++j) s += cb.grad[3 * k + j] * r.r1[i][j];
      Fe[off + a] += w * s;
    }
    off += cb.n;
  }
  const ComponentBasis& cp = eb.comp[dim];
  for (int a = 0; a < cp.n; ++a) Fe[off + a] += w * cp.value[static_cast<size_t>(q) * cp.n + a] * r.rq;
}

/// An element's tangent summed over its points (the element's Gauss points, or the immersed points in it):
/// sum_p B_p^T C_p B_p. Each point's columns are tabulated (their effect on r0_i, r1_ij and rq, a row of the
/// element's unknowns each) beside its test functions' values and gradients (times the weight); a chunk of
/// points is then added by one GEMM per velocity component and one for the pressure rows. Measured on the 3D
/// compound capsule at 16^3 with bodies from the fluid mesh (287 k immersed points in 208 elements): a
/// refresh of the points' tangent 2.9 s against 6.5 s when each point wrote the element matrix a column at a
/// time (docs/notes/2026-11-28-dc-3d-assembly.md).
/// velocity_only: the points' terms have no pressure (no d r1 / d p, rq = 0: the immersed points), so Ke is
/// the velocity block alone (the first off_[dim] local unknowns): about a third fewer operations.
class TangentAccumulator {
 public:
  /// Starts an element: Ke (n_loc x n_loc, row-major, zeroed by the caller; n_loc the element's unknowns, or
  /// with velocity_only its velocity unknowns) receives the sums.
  void start(const ElementBasis& eb, int dim, std::vector<double>* Ke, bool velocity_only = false) {
    dim_ = dim;
    K_ = Ke;
    velocity_only_ = velocity_only;
    off_[0] = 0;
    for (int c = 0; c <= dim; ++c) n_[c] = eb.comp[c].n, off_[c + 1] = off_[c] + n_[c];
    n_loc_ = off_[velocity_only ? dim : dim + 1];
    points_ = 0;
    const size_t rows = static_cast<size_t>(kChunk) * (dim + 1);
    for (int i = 0; i < dim; ++i) {
      X_[i].resize(rows * n_loc_);
      W_[i].resize(rows * n_[i]);
    }
    Xq_.resize(static_cast<size_t>(kChunk) * n_loc_);
    Wq_.resize(static_cast<size_t>(kChunk) * n_[dim]);
  }
  /// Point q of eb (the element's functions, with weight w).
  void add(const ElementBasis& eb, int q, double w, const PointTangent& t, double dv_dU, double da_dU) {
    const int D = dim_, R = D + 1, p = points_;
    // Test side: w N_a and w dN_a/dx_j, rows R p .. R p + D of W_i.
    for (int i = 0; i < D; ++i) {
      const ComponentBasis& cb = eb.comp[i];
      double* Wi = W_[i].data() + static_cast<size_t>(R * p) * n_[i];
      for (int a = 0; a < n_[i]; ++a) {
        const size_t k = static_cast<size_t>(q) * n_[i] + a;
        Wi[a] = w * cb.value[k];
        for (int j = 0; j < D; ++j) Wi[static_cast<size_t>(1 + j) * n_[i] + a] = w * cb.grad[3 * k + j];
      }
    }
    const ComponentBasis& cp = eb.comp[D];
    // (-log_view's counts: per velocity column D (5 + 4 D + 2 D^2) + 2 D + 1, per pressure column D^2)
    CELLFSI_PETSC(PetscLogFlops(off_[D] * (D * (5.0 + 4 * D + 2 * D * D) + 2.0 * D + 1) +
                                (velocity_only_ ? 0.0 : n_[D] * D * D)));
    if (!velocity_only_)
      for (int a = 0; a < n_[D]; ++a)
        Wq_[static_cast<size_t>(p) * n_[D] + a] = w * cp.value[static_cast<size_t>(q) * n_[D] + a];
    // Trial side: row 0 of X_i is d r0_i / d U_col, row 1 + j d r1_ij / d U_col; Xq d rq / d U_col.
    double* S[3];
    double* T[3][3];
    for (int i = 0; i < D; ++i) {
      S[i] = X_[i].data() + static_cast<size_t>(R * p) * n_loc_;
      for (int j = 0; j < D; ++j) T[i][j] = S[i] + static_cast<size_t>(1 + j) * n_loc_;
    }
    double* Q = Xq_.data() + static_cast<size_t>(p) * n_loc_;
    for (int k = 0; k < D; ++k) {
      const ComponentBasis& cb = eb.comp[k];
      for (int b = 0; b < n_[k]; ++b) {
        const size_t m = static_cast<size_t>(q) * n_[k] + b;
        const double Nb = cb.value[m];
        double dNb[3] = {0, 0, 0};
        for (int l = 0; l < D; ++l) dNb[l] = cb.grad[3 * m + l];
        const int col = off_[k] + b;
        for (int i = 0; i < D; ++i) {
          double sv = t.dr0_dv[i][k] * Nb;
          for (int l = 0; l < D; ++l) sv += t.dr0_ddv[i][k][l] * dNb[l];
          S[i][col] = dv_dU * sv + da_dU * t.dr0_da[i][k] * Nb;
          for (int j = 0; j < D; ++j) {
            double tv = t.dr1_dv[i][j][k] * Nb;
            for (int l = 0; l < D; ++l) tv += t.dr1_ddv[i][j][k][l] * dNb[l];
            T[i][j][col] = dv_dU * tv;
          }
        }
        if (velocity_only_) continue;
        double sq = 0;
        for (int l = 0; l < D; ++l) sq += t.drq_ddv[k][l] * dNb[l];
        Q[col] = dv_dU * sq;
      }
    }
    // Pressure columns: momentum rows only (the pressure block is zero).
    for (int b = 0; b < (velocity_only_ ? 0 : n_[D]); ++b) {
      const double Nb = cp.value[static_cast<size_t>(q) * n_[D] + b];
      const int col = off_[D] + b;
      Q[col] = 0.0;
      for (int i = 0; i < D; ++i) {
        S[i][col] = 0.0;
        for (int j = 0; j < D; ++j) T[i][j][col] = t.dr1_dp[i][j] * Nb;
      }
    }
    if (++points_ == kChunk) flush();
  }
  /// Adds the points not yet added (call before Ke is read).
  void flush() {
    if (points_ == 0) return;
    // Ke is row-major: read by BLAS (column-major) it is Ke^T, and the rows of component i its columns
    // off_i ... off_i + n_i: Ke^T[:, off_i + a] += X_i^T W_i[:, a] over the chunk's rows.
    const PetscBLASInt m = n_loc_;
    const double alpha = 1.0, beta = 1.0;
    double* K = K_->data();
    for (int c = 0; c <= (velocity_only_ ? dim_ - 1 : dim_); ++c) {
      const PetscBLASInt n = n_[c], k = c < dim_ ? points_ * (dim_ + 1) : points_;
      const double* X = c < dim_ ? X_[c].data() : Xq_.data();
      const double* W = c < dim_ ? W_[c].data() : Wq_.data();
      BLASgemm_("N", "T", &m, &n, &k, &alpha, X, &m, W, &n, &beta, K + static_cast<size_t>(off_[c]) * n_loc_,
                &m);
      CELLFSI_PETSC(PetscLogFlops(2.0 * m * n * k));
    }
    points_ = 0;
  }

 private:
  static constexpr int kChunk = 64;
  int dim_ = 2, n_loc_ = 0, points_ = 0;
  bool velocity_only_ = false;
  int off_[5] = {0, 0, 0, 0, 0}, n_[4] = {0, 0, 0, 0};
  std::vector<double>* K_ = nullptr;
  std::vector<double> X_[3], W_[3], Xq_, Wq_;
};

/// The L2 projection's coefficients: M^{-1} load for the mass matrix M of n functions given as triplets, by
/// sparse Cholesky. Throws std::runtime_error "<what> mass matrix is singular" if it fails.
Eigen::VectorXd solve_mass_matrix(int n, const std::vector<Eigen::Triplet<double>>& entries,
                                  const Eigen::VectorXd& load, const std::string& what) {
  Eigen::SparseMatrix<double> M(n, n);
  M.setFromTriplets(entries.begin(), entries.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(M);
  if (ldlt.info() != Eigen::Success) throw std::runtime_error(what + " mass matrix is singular");
  return ldlt.solve(load);
}

/// Global indices of an element's local unknowns (add_point_residual's local numbering).
std::vector<PetscInt> local_indices(const ElementBasis& eb, int dim) {
  std::vector<PetscInt> idx;
  for (int c = 0; c <= dim; ++c) idx.insert(idx.end(), eb.comp[c].index.begin(), eb.comp[c].index.end());
  return idx;
}

}  // namespace

void DcFluidOptions::set_from_options() {
  density = get_real("-fluid_density", density);
  viscosity = get_real("-fluid_viscosity", viscosity);
  rho_inf = get_real("-fluid_rho_inf", rho_inf);
  dt = get_real("-fluid_dt", dt);
  penalty = get_real("-fluid_dc_penalty", penalty);
  PetscBool flag = stokes ? PETSC_TRUE : PETSC_FALSE, set = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsGetBool(nullptr, nullptr, "-fluid_stokes", &flag, &set));
  stokes = flag == PETSC_TRUE;
  validate();
}

void DcFluidOptions::validate() const {
  require(density > 0, "density must be > 0 g/cm^3, got " + std::to_string(density));
  require(viscosity > 0, "viscosity must be > 0 g/(cm s), got " + std::to_string(viscosity));
  require(rho_inf >= 0 && rho_inf <= 1, "rho_inf must be in [0, 1], got " + std::to_string(rho_inf));
  require(dt > 0, "dt must be > 0 s, got " + std::to_string(dt));
  require(penalty > 2.0,
          "the Nitsche constant -fluid_dc_penalty must be > 2 (coercivity, dc_fluid.hpp), got " +
              std::to_string(penalty));
  require(newton_max_it >= 1, "newton_max_it must be >= 1");
  for (int d = 0; d < 3; ++d)
    for (int s = 0; s < 2; ++s)
      require(wall_velocity[d][s][d] == 0.0, "the wall velocity of direction " + std::to_string(d) +
                                                 " must be tangential (its component " + std::to_string(d) +
                                                 " is " + std::to_string(wall_velocity[d][s][d]) + ")");
}

DivConformingFluid::DivConformingFluid(MPI_Comm comm, const DivConformingSpace& space,
                                       const DcFluidOptions& options)
    : comm_(comm), space_(space), opt_(options) {
  opt_.validate();
  alpha_ = GeneralizedAlpha::from_rho_inf(opt_.rho_inf, opt_.dt);
  const int n = space_.n_dofs(), D = space_.dim(), n_el = space_.n_elements();
  U_.assign(n, 0.0);
  Udot_.assign(n, 0.0);
  fixed_rows_ = space_.wall_normal_dofs();
  fixed_rows_.push_back(space_.offset(D));  // the pressure pin
  std::sort(fixed_rows_.begin(), fixed_rows_.end());

  // Elements: contiguous ranges of the linear index. Unknowns: numbered by the lowest rank whose elements
  // touch them, rank by rank (natural order within a rank), and that numbering cut into equal runs of rows.
  // (The first plane of elements touches the first k' + 1 planes of unknowns, the open knot vector's extra
  // functions: rows by first touch would give rank 0 two planes more than the others, and elements cut to
  // equal rows would give it a third of the others' elements.)
  int rank = 0, size = 1;
  CELLFSI_PETSC(MPI_Comm_rank(comm_, &rank));
  CELLFSI_PETSC(MPI_Comm_size(comm_, &size));
  auto first_element = [&](int r) { return static_cast<int>(static_cast<long>(n_el) * r / size); };
  elem_begin_ = first_element(rank);
  elem_end_ = first_element(rank + 1);
  std::vector<int> owner(n, size);
  ElementBasis eb;
  for (int r = 0; r < size; ++r)
    for (int e = first_element(r); e < first_element(r + 1); ++e) {
      const Index3 ei = space_.element_multi_index(e);
      space_.evaluate(ei, space_.element_rule(ei, 1), eb);  // indices only
      for (PetscInt g : local_indices(eb, D)) owner[g] = std::min(owner[g], r);
    }
  petsc_index_.assign(n, -1);
  PetscInt next = 0;
  for (int r = 0; r < size; ++r)
    for (int g = 0; g < n; ++g)
      if (owner[g] == r) petsc_index_[g] = next++;
  row_begin_ = static_cast<PetscInt>(static_cast<std::int64_t>(n) * rank / size);
  row_end_ = static_cast<PetscInt>(static_cast<std::int64_t>(n) * (rank + 1) / size);
  owned_natural_.assign(static_cast<std::size_t>(row_end_ - row_begin_), -1);
  for (int g = 0; g < n; ++g)
    if (petsc_index_[g] >= row_begin_ && petsc_index_[g] < row_end_)
      owned_natural_[petsc_index_[g] - row_begin_] = g;
  for (int g : fixed_rows_)
    if (petsc_index_[g] >= row_begin_ && petsc_index_[g] < row_end_) {
      owned_fixed_.push_back(petsc_index_[g]);
      owned_fixed_natural_.push_back(g);
    }

  for (int e = elem_begin_; e < elem_end_; ++e) {
    const Index3 ei = space_.element_multi_index(e);
    space_.evaluate(ei, space_.element_rule(ei, 1), eb);  // indices only
    const std::vector<PetscInt> idx = local_indices(eb, D);
    n_local_ = static_cast<int>(idx.size());
    element_unknowns_.insert(element_unknowns_.end(), idx.begin(), idx.end());
  }
  pressure_mass_.assign(space_.n_pressure(), 0.0);
  for_owned_elements(n_gauss(), [&](const ElementBasis& b) {
    const ComponentBasis& cb = b.comp[D];
    for (int q = 0; q < b.n_points; ++q)
      for (int a = 0; a < cb.n; ++a)
        pressure_mass_[cb.index[a] - space_.offset(D)] += b.weight[q] * cb.value[q * cb.n + a];
  });
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, pressure_mass_.data(), static_cast<int>(pressure_mass_.size()),
                              MPI_DOUBLE, MPI_SUM, comm_));

  CELLFSI_PETSC(VecCreateMPI(comm_, row_end_ - row_begin_, n, &F_));
  CELLFSI_PETSC(VecDuplicate(F_, &x_));
  CELLFSI_PETSC(VecScatterCreateToAll(x_, &to_all_, &x_all_));
  CELLFSI_PETSC(KSPCreate(comm_, &ksp_));
  CELLFSI_PETSC(KSPSetOptionsPrefix(ksp_, "fluid_"));
  CELLFSI_PETSC(KSPSetType(ksp_, KSPPREONLY));
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp_, &pc));
  CELLFSI_PETSC(PCSetType(pc, PCLU));
  CELLFSI_PETSC(PCFactorSetMatSolverType(pc, MATSOLVERMUMPS));
  CELLFSI_PETSC(KSPSetFromOptions(ksp_));  // the command line wins over the defaults above
  // (The matrix is made when first needed: matrix().)
}

Mat DivConformingFluid::matrix() {
  if (J_) return J_;
  J_ = create_matrix(nullptr);
  CELLFSI_PETSC(KSPSetOperators(ksp_, J_, J_));
  // MUMPS's relative pivot threshold CNTL(1): 0.5 instead of its 0.01. With 0.01 the saddle-point matrix
  // (mass, viscous and Nitsche rows of different scales, the zero pressure block) is factored with enough
  // growth that the continuity rows of a one-iteration solve hold only to ~1e-10 of |grad v| (7e-11 measured
  // on the manufactured solution at 16^2); with 0.5, 1e-14. -fluid_mat_mumps_cntl_1 still overrides it (MUMPS
  // reads its options when it factors).
  PC pc;
  CELLFSI_PETSC(KSPGetPC(ksp_, &pc));
  PCType pc_type;
  MatSolverType solver_type = nullptr;
  CELLFSI_PETSC(PCGetType(pc, &pc_type));
  if (pc_type && std::string(pc_type) == PCLU) CELLFSI_PETSC(PCFactorGetMatSolverType(pc, &solver_type));
  if (solver_type && std::string(solver_type) == MATSOLVERMUMPS) {
    Mat F;
    CELLFSI_PETSC(PCFactorSetUpMatSolverType(pc));
    CELLFSI_PETSC(PCFactorGetMatrix(pc, &F));
    CELLFSI_PETSC(MatMumpsSetCntl(F, 1, 0.5));
  }
  return J_;
}

void DivConformingFluid::release_matrix() {
  if (!J_) return;
  CELLFSI_PETSC(KSPReset(ksp_));  // (its type and options stay; its operators and factors go)
  MatDestroy(&J_);
#ifdef __GLIBC__
  malloc_trim(0);  // (as FluidSolver::release_jacobian_matrix: glibc keeps a large matrix's pages otherwise)
#endif
}

DivConformingFluid::~DivConformingFluid() {
  KSPDestroy(&ksp_);
  MatDestroy(&J_);
  VecScatterDestroy(&to_all_);
  VecDestroy(&x_all_);
  VecDestroy(&x_);
  VecDestroy(&F_);
  own_unknowns_.destroy();
  for (GatherPart& g : parts_) g.of_elements.destroy();
}

template <class F>
void DivConformingFluid::for_owned_elements(int n_gauss, F&& f) const {
  ElementBasis eb;
  for (int e = elem_begin_; e < elem_end_; ++e) {
    if (n_gauss == this->n_gauss()) {
      f(element_basis(e));
      continue;
    }
    const Index3 ei = space_.element_multi_index(e);
    space_.evaluate(ei, space_.element_rule(ei, n_gauss), eb);
    f(eb);
  }
}

void DivConformingFluid::gather_block(const int* members, int m, int local_first, int n, const double* src,
                                      int shift, std::vector<double>& out) const {
  out.resize(static_cast<size_t>(n) * m);
  for (int e = 0; e < m; ++e) {
    const int* idx =
        element_unknowns_.data() + static_cast<size_t>(members[e] - elem_begin_) * n_local_ + local_first;
    for (int b = 0; b < n; ++b) out[static_cast<size_t>(b) * m + e] = src[idx[b] - shift];
  }
}

const int* DivConformingFluid::unknowns_of(int e, std::vector<int>& scratch) const {
  if (e >= elem_begin_ && e < elem_end_)
    return element_unknowns_.data() + static_cast<size_t>(e - elem_begin_) * n_local_;
  const Index3 ei = space_.element_multi_index(e);
  ElementBasis eb;
  space_.evaluate(ei, space_.element_rule(ei, 1), eb);  // indices only
  const std::vector<PetscInt> idx = local_indices(eb, space_.dim());
  scratch.assign(idx.begin(), idx.end());
  return scratch.data();
}

const std::vector<std::vector<int>>& DivConformingFluid::elements_by_class() const {
  if (class_elements_.empty()) {
    class_elements_.resize(static_cast<size_t>(std::pow(2 * space_.degree() + 5, space_.dim())));
    for (int e = elem_begin_; e < elem_end_; ++e) class_elements_[basis_class(e)].push_back(e);
  }
  return class_elements_;
}

int DivConformingFluid::basis_class(int e) const {
  const int D = space_.dim(), k = space_.degree(), classes = 2 * k + 5;
  const Index3 ei = space_.element_multi_index(e);
  // Per direction: 0 for an element far from the walls (every element of a periodic direction), else
  // 1 + its distance from the near wall, counted from each end apart.
  int key = 0;
  for (int d = D - 1; d >= 0; --d) {
    int c = 0;
    const int n = space_.n_elements(d);
    if (!space_.periodic(d)) {
      if (ei[d] <= k + 1)
        c = 1 + ei[d];
      else if (n - 1 - ei[d] <= k + 1)
        c = k + 3 + (n - 1 - ei[d]);
    }
    key = key * classes + c;
  }
  return key;
}

const ElementBasis& DivConformingFluid::element_basis(int e) const {
  const int D = space_.dim(), classes = 2 * space_.degree() + 5;
  const Index3 ei = space_.element_multi_index(e);
  if (space_.is_mapped()) {
    // No two elements share their values through the map, and a cache per element would hold 45 kB each
    // (k = 3 in 2D; 2.2 GB at the narrowing scene's 384 x 128): each call evaluates.
    if (basis_cache_.empty()) basis_cache_.resize(1);
    if (!basis_cache_[0]) basis_cache_[0] = std::make_unique<CachedBasis>();
    basis_cache_[0]->element = ei;
    space_.evaluate(ei, space_.element_rule(ei, n_gauss()), basis_cache_[0]->basis);
    return basis_cache_[0]->basis;
  }
  const int key = basis_class(e);
  if (basis_cache_.empty()) basis_cache_.resize(static_cast<size_t>(std::pow(classes, D)));
  std::unique_ptr<CachedBasis>& slot = basis_cache_[static_cast<size_t>(key)];
  if (!slot) {
    slot = std::make_unique<CachedBasis>();
    slot->element = ei;
    space_.evaluate(ei, space_.element_rule(ei, n_gauss()), slot->basis);
  }
  ElementBasis& eb = slot->basis;
  if (slot->element != ei) {
    Vec3 shift = Vec3::Zero();
    for (int d = 0; d < D; ++d) shift[d] = (ei[d] - slot->element[d]) * space_.element_size(d);
    for (Vec3& x : eb.x) x += shift;
    slot->element = ei;
  }
  const int* idx = element_unknowns_.data() + static_cast<size_t>(e - elem_begin_) * n_local_;
  for (int c = 0, a0 = 0; c <= D; ++c) {
    for (int a = 0; a < eb.comp[c].n; ++a) eb.comp[c].index[a] = idx[a0 + a];
    a0 += eb.comp[c].n;
  }
  return eb;
}

Mat DivConformingFluid::create_matrix(const std::vector<char>* wanted, std::vector<char>* touching) const {
  // The pattern of each owned row (PETSc numbering): the union of the unknowns of the elements in its
  // support, a velocity row all of them, a pressure row their velocity columns and its own diagonal (for the
  // pin's unit row). Each element's unknowns, then each unknown's elements (both compressed, O(elements x
  // their unknowns)), then one owned row at a time with a marker, counted and then inserted: a list per row
  // filled element by element held each row's columns about 36 times over (at 64^3 in 3D the OOM killer
  // stopped the run at 13 GB per rank). With `wanted` only the elements that touch a wanted unknown are
  // listed (and marked in `touching`), and only the wanted rows get a pattern.
  const int n = space_.n_dofs(), D = space_.dim(), n_el = space_.n_elements();
  std::vector<int> el_start(n_el + 1, 0), el_unknowns;
  int n_vel = 0;  // an element's velocity unknowns (the first of its list)
  ElementBasis eb;
  if (touching) touching->assign(n_el, 0);
  for (int e = 0; e < n_el; ++e) {
    const Index3 ei = space_.element_multi_index(e);
    space_.evaluate(ei, space_.element_rule(ei, 1), eb);  // indices only
    const std::vector<PetscInt> idx = local_indices(eb, D);
    n_vel = static_cast<int>(idx.size()) - eb.comp[D].n;
    const bool listed =
        !wanted || std::any_of(idx.begin(), idx.end(), [&](PetscInt g) { return (*wanted)[g] != 0; });
    if (listed) {
      for (PetscInt g : idx) el_unknowns.push_back(static_cast<int>(g));
      if (touching) (*touching)[e] = 1;
    }
    el_start[e + 1] = static_cast<int>(el_unknowns.size());
  }
  std::vector<int> fn_start(n + 1, 0), fn_elements(el_unknowns.size());
  for (int g : el_unknowns) ++fn_start[g + 1];
  for (int g = 0; g < n; ++g) fn_start[g + 1] += fn_start[g];
  {
    std::vector<int> fill(fn_start.begin(), fn_start.end() - 1);
    for (int e = 0; e < n_el; ++e)
      for (int a = el_start[e]; a < el_start[e + 1]; ++a) fn_elements[fill[el_unknowns[a]]++] = e;
  }
  const std::vector<int>& natural_of = owned_natural_;  // owned PETSc row -> natural unknown
  const PetscInt n_own = row_end_ - row_begin_;
  std::vector<PetscInt> stamp(n, -1), cols;
  // The columns of owned row i (natural unknown g) into cols, PETSc numbering, sorted (none for a row not
  // wanted).
  auto row_columns = [&](PetscInt i) {
    cols.clear();
    const int g = natural_of[i];
    if (wanted && !(*wanted)[g]) return;
    const bool pressure = g >= space_.offset(D);
    for (int f = fn_start[g]; f < fn_start[g + 1]; ++f) {
      const int e = fn_elements[f];
      const int end = pressure ? el_start[e] + n_vel : el_start[e + 1];
      for (int a = el_start[e]; a < end; ++a)
        if (stamp[el_unknowns[a]] != i) {
          stamp[el_unknowns[a]] = i;
          cols.push_back(petsc_index_[el_unknowns[a]]);
        }
    }
    if (pressure && stamp[g] != i) {
      stamp[g] = i;
      cols.push_back(petsc_index_[g]);
    }
    std::sort(cols.begin(), cols.end());
  };
  std::vector<PetscInt> d_nnz(n_own), o_nnz(n_own);
  for (PetscInt i = 0; i < n_own; ++i) {
    row_columns(i);
    d_nnz[i] =
        std::count_if(cols.begin(), cols.end(), [&](PetscInt c) { return c >= row_begin_ && c < row_end_; });
    o_nnz[i] = static_cast<PetscInt>(cols.size()) - d_nnz[i];
  }
  Mat J = nullptr;
  CELLFSI_PETSC(MatCreateAIJ(comm_, n_own, n_own, n, n, 0, d_nnz.data(), 0, o_nnz.data(), &J));
  CELLFSI_PETSC(MatSetOption(J, MAT_KEEP_NONZERO_PATTERN, PETSC_TRUE));
  // Insert the pattern once (zeros), so that later assemblies never allocate.
  std::fill(stamp.begin(), stamp.end(), -1);
  std::vector<PetscScalar> zeros;
  for (PetscInt i = 0; i < n_own; ++i) {
    row_columns(i);
    if (cols.empty()) continue;
    zeros.assign(cols.size(), 0.0);
    const PetscInt row = row_begin_ + i;
    CELLFSI_PETSC(MatSetValues(J, 1, &row, static_cast<PetscInt>(cols.size()), cols.data(), zeros.data(),
                               INSERT_VALUES));
  }
  CELLFSI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatSetOption(J, MAT_NEW_NONZERO_LOCATION_ERR, PETSC_TRUE));
  // The element matrices carry the zero pressure-pressure block; added zeros are skipped, not inserted.
  CELLFSI_PETSC(MatSetOption(J, MAT_IGNORE_ZERO_ENTRIES, PETSC_TRUE));
  return J;
}

Vec3 DivConformingFluid::wall_velocity(int d, int side, const Vec3& x, double t, const PointVec& n) const {
  Vec3 v = opt_.wall_velocity_field ? opt_.wall_velocity_field(x, t) : opt_.wall_velocity[d][side];
  // Only the tangential part is imposed (weakly); the normal one is the strong 0.
  const double vn = v[0] * n[0] + v[1] * n[1] + v[2] * n[2];
  for (int i = 0; i < 3; ++i) v[i] -= vn * n[i];
  return v;
}

void DivConformingFluid::assemble(const Levels& lv, Vec F, Mat J, bool with_immersed,
                                  const RowSubset* subset) const {
  const int D = space_.dim();
  CELLFSI_PETSC(VecZeroEntries(F));
  if (J) CELLFSI_PETSC(MatZeroEntries(J));
  ElementBasis face_basis;
  const ElementBasis* current = &face_basis;  // the element's basis (cached) or a face's
  std::vector<double> Fe, Ke;
  TangentAccumulator tangent;

  auto point_state = [&](int q) {
    const ElementBasis& eb = *current;
    PointState s;
    const auto pv = DivConformingSpace::interpolate(eb, q, D, lv.v.data());
    const auto pa = DivConformingSpace::interpolate_velocity(eb, q, D, lv.a.data());
    for (int i = 0; i < D; ++i) {
      s.v[i] = pv.v[i];
      s.a[i] = pa[i];
      for (int j = 0; j < D; ++j) s.dv[i][j] = pv.grad[i][j];
    }
    s.p = pv.p;  // lv.v carries U's pressure
    return s;
  };
  // Integrates a kernel (residual at point q; tangent into t if t is not null) over the points of eb and adds
  // the element's residual and tangent to F and J.
  auto integrate = [&](const std::function<PointResidual(int, const PointState&, PointTangent*)>& kernel) {
    const ElementBasis& eb = *current;
    int n_loc = 0;
    for (int c = 0; c <= D; ++c) n_loc += eb.comp[c].n;
    Fe.assign(n_loc, 0.0);
    if (J) {
      Ke.assign(static_cast<size_t>(n_loc) * n_loc, 0.0);
      tangent.start(eb, D, &Ke);
    }
    PointTangent t;  // (zeroed once per element; the kernels assign it whole)
    for (int q = 0; q < eb.n_points; ++q) {
      PointResidual r = kernel(q, point_state(q), J ? &t : nullptr);
      if (!eb.piola.empty()) {  // a mapped space: the test side through the map (dc_piola.hpp)
        r = piola_residual(eb.piola[q], r);
        if (J) t = piola_tangent(eb.piola[q], t);
      }
      add_point_residual(eb, q, D, eb.weight[q], r, Fe);
      if (J) tangent.add(eb, q, eb.weight[q], t, lv.dv_dU, lv.da_dU);
    }
    if (J) tangent.flush();
    std::vector<PetscInt> idx = local_indices(eb, D), rows;
    if (subset) {  // (MatSetValues skips negative rows; F is left alone)
      rows = idx;
      for (PetscInt& g : rows) g = subset->rows[g] ? petsc_index_[g] : -1;
    }
    for (PetscInt& g : idx) g = petsc_index_[g];
    if (!subset) CELLFSI_PETSC(VecSetValues(F, n_loc, idx.data(), Fe.data(), ADD_VALUES));
    const PetscInt* row_idx = subset ? rows.data() : idx.data();
    if (J) CELLFSI_PETSC(MatSetValues(J, n_loc, row_idx, n_loc, idx.data(), Ke.data(), ADD_VALUES));
  };

  // nu at point q of eb: the field's where there is one, else lv.nu.
  const bool field = lv.viscosity_field && !nu_field_.empty();
  auto nu_at = [&](int q) {
    if (!field) return lv.nu;
    const ComponentBasis& cb = current->comp[D];
    double nu = 0;
    for (int a = 0; a < cb.n; ++a) nu += nu_field_[cb.index[a] - space_.offset(D)] * cb.value[q * cb.n + a];
    return nu;
  };

  InteriorParameters ip;
  ip.dim = D;
  ip.nu = lv.nu;
  ip.convection = lv.convection;
  const bool mapped = space_.is_mapped();
  if (!J && !mapped) {  // the same sums, without the kernels' generality (on a box)
    static const PetscLogEvent interior_event = register_log_event("cellfsi fluid", "DcInterior");
    EventScope ev(interior_event);
    interior_residual(lv, F);
  }
  for (int e = elem_begin_; e < elem_end_ && (J || mapped); ++e) {
    if (subset && !subset->elements[e]) continue;
    current = &element_basis(e);
    integrate([&](int q, const PointState& s, PointTangent* t) {
      const Vec3 g = lv.g ? lv.g(current->x[q]) : Vec3(Vec3::Zero());
      for (int i = 0; i < 3; ++i) ip.g[i] = g[i];
      ip.nu = nu_at(q);
      if (t) *t = dc_interior_tangent(s, ip);
      return dc_interior_residual(s, ip);
    });
  }

  if (lv.nitsche) {
    NitscheParameters np;
    np.dim = D;
    std::vector<double> grad_xi;  // |grad xi_d| at a face's points (1 on a box)
    for (int d = 0; d < D; ++d) {
      if (space_.periodic(d)) continue;
      // (on a mapped space the element's size across the wall is h^ / |grad xi_d| at each point)
      const double beta_per_nu =
          opt_.penalty * (space_.degree() + 1) * (space_.degree() + 1) / space_.element_size(d);
      for (int side = 0; side < 2; ++side) {
        np.n = {0, 0, 0};
        np.n[d] = side == 0 ? -1.0 : 1.0;
        for (int e = elem_begin_; e < elem_end_; ++e) {
          if (subset && !subset->elements[e]) continue;
          const Index3 ei = space_.element_multi_index(e);
          if (ei[d] != (side == 0 ? 0 : space_.n_elements(d) - 1)) continue;
          space_.evaluate(ei, space_.face_rule(ei, d, side, n_gauss()), face_basis);
          // A mapped face: the measure J |G^T e_d| dA^ (Nanson; evaluate gave J), its outward normal
          // +-G^T e_d / |G^T e_d| per point.
          grad_xi.assign(face_basis.n_points, 1.0);
          for (size_t q = 0; q < face_basis.piola.size(); ++q) {
            grad_xi[q] = face_basis.piola[q].G.row(d).norm();
            face_basis.weight[q] *= grad_xi[q];
          }
          current = &face_basis;
          integrate([&](int q, const PointState& s, PointTangent* t) {
            if (mapped) {
              const PiolaPoint& pp = face_basis.piola[q];
              for (int i = 0; i < 3; ++i) np.n[i] = (side == 0 ? -1.0 : 1.0) * pp.G(d, i) / grad_xi[q];
            }
            const Vec3 vw = wall_velocity(d, side, face_basis.x[q], lv.t, np.n);
            for (int i = 0; i < 3; ++i) np.v_wall[i] = vw[i];
            np.nu = nu_at(q);
            np.beta = beta_per_nu * grad_xi[q] * np.nu;
            if (t) *t = dc_nitsche_tangent(np);
            return dc_nitsche_residual(s, np);
          });
        }
      }
    }
  }
  if (with_immersed) {
    // (-log_view: the immersed points' share of a residual or tangent)
    static const PetscLogEvent immersed_event = register_log_event("cellfsi fluid", "DcImmersed");
    EventScope ev(immersed_event);
    assemble_immersed(lv, F, J);
  }
  CELLFSI_PETSC(VecAssemblyBegin(F));
  CELLFSI_PETSC(VecAssemblyEnd(F));
  if (J) {
    CELLFSI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
    CELLFSI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  }
}

void DivConformingFluid::interior_residual(const Levels& lv, Vec F) const {
  // The sizes of the common spaces as constants, so the compiler unrolls the point loops (256 x 128, k' = 2:
  // see interior_residual_sized); any other size takes the same code with run-time sizes.
  const int D = space_.dim(), k = space_.degree();
  if (!opt_.body_force_field) return interior_residual_batched(lv, F);
  if (D == 2 && k == 2) return interior_residual_sized<2, 12, 9>(lv, F);
  if (D == 2 && k == 3) return interior_residual_sized<2, 20, 16>(lv, F);
  if (D == 3 && k == 2) return interior_residual_sized<3, 36, 27>(lv, F);
  if (D == 2) return interior_residual_sized<2, 0, 0>(lv, F);
  interior_residual_sized<3, 0, 0>(lv, F);
}

template <int D, int NV, int NP>
void DivConformingFluid::interior_residual_sized(const Levels& lv, Vec F) const {
  // dc_interior_residual at every Gauss point, written out: r0 = a + c (v.grad)v - g, r1 = nu (grad v +
  // grad v^T) - p I, rq = div v, integrated against the element's functions. NV (NP): functions per velocity
  // component (pressure) of an element, 0 if only known at run time. The element's coefficients are gathered
  // once, and its rows added into F's local array directly (rows of other ranks by one VecSetValues). A step
  // driven this way agrees with the fluid's own Newton, whose residual is the generic assembly's
  // (tests/unit/fluid/test_dc_immersed_fluid.cpp), and its central differences with the tangent
  // (tests/unit/fluid/test_div_conforming.cpp).
  const bool field = lv.viscosity_field && !nu_field_.empty();
  const bool uniform_g = !opt_.body_force_field;
  const Vec3 g_uniform = uniform_g && lv.g ? lv.g(Vec3::Zero()) : Vec3(Vec3::Zero());
  // Functions of an element: (k' + 2) (k' + 1)^(D - 1) per velocity component, (k' + 1)^D of the pressure.
  const int k = space_.degree();
  const int nv = NV ? NV : (k + 2) * static_cast<int>(std::pow(k + 1, D - 1));
  const int np = NP ? NP : static_cast<int>(std::pow(k + 1, D));
  const int n_max = D * nv + np;
  std::vector<double> buffers(4 * static_cast<size_t>(n_max));
  double *ue = buffers.data(), *ae = ue + n_max, *Fe = ae + n_max, *nue = Fe + n_max;
  std::vector<PetscInt> idx(n_max);
  std::vector<PetscInt> other_rows;  // rows of other ranks (at the partition's edges), added after the loop
  std::vector<double> other_values;
  PetscScalar* f;
  CELLFSI_PETSC(VecGetArray(F, &f));
  for (int e = elem_begin_; e < elem_end_; ++e) {
    const ElementBasis& eb = element_basis(e);
    for (int c = 0; c <= D; ++c) {
      const ComponentBasis& cb = eb.comp[c];
      for (int a = 0; a < cb.n; ++a) {
        const int g = cb.index[a];
        ue[c * nv + a] = lv.v[g];
        ae[c * nv + a] = lv.a[g];
        Fe[c * nv + a] = 0.0;
        idx[c * nv + a] = petsc_index_[g];
        if (c == D && field) nue[a] = nu_field_[g - space_.offset(D)];
      }
    }
    const double* pe = ue + D * nv;
    for (int q = 0; q < eb.n_points; ++q) {
      double v[3] = {0, 0, 0}, a[3] = {0, 0, 0}, dv[3][3] = {}, p = 0, nu = lv.nu;
      for (int c = 0; c < D; ++c) {
        const double* N = &eb.comp[c].value[static_cast<size_t>(q) * nv];
        const double* dN = &eb.comp[c].grad[static_cast<size_t>(q) * nv * 3];
        const double* uc = ue + c * nv;
        const double* ac = ae + c * nv;
        for (int b = 0; b < nv; ++b) {
          v[c] += N[b] * uc[b];
          a[c] += N[b] * ac[b];
          for (int j = 0; j < D; ++j) dv[c][j] += dN[3 * b + j] * uc[b];
        }
      }
      const double* Np = &eb.comp[D].value[static_cast<size_t>(q) * np];
      if (field) nu = 0;
      for (int b = 0; b < np; ++b) {
        p += Np[b] * pe[b];
        if (field) nu += Np[b] * nue[b];
      }
      const Vec3 g = uniform_g ? g_uniform : (lv.g ? lv.g(eb.x[q]) : Vec3(Vec3::Zero()));
      const double w = eb.weight[q];
      double r0[3], r1[3][3], rq = 0;
      for (int i = 0; i < D; ++i) {
        double conv = 0;
        for (int l = 0; l < D; ++l) conv += v[l] * dv[i][l];
        r0[i] = w * (a[i] + lv.convection * conv - g[i]);
        for (int j = 0; j < D; ++j) r1[i][j] = w * (nu * (dv[i][j] + dv[j][i]) - (i == j ? p : 0.0));
        rq += dv[i][i];
      }
      for (int c = 0; c < D; ++c) {
        const double* N = &eb.comp[c].value[static_cast<size_t>(q) * nv];
        const double* dN = &eb.comp[c].grad[static_cast<size_t>(q) * nv * 3];
        double* Fc = Fe + c * nv;
        for (int b = 0; b < nv; ++b) {
          double r = N[b] * r0[c];
          for (int j = 0; j < D; ++j) r += dN[3 * b + j] * r1[c][j];
          Fc[b] += r;
        }
      }
      double* Fp = Fe + D * nv;
      for (int b = 0; b < np; ++b) Fp[b] += w * Np[b] * rq;
    }
    for (int b = 0; b < n_max; ++b) {
      if (idx[b] >= row_begin_ && idx[b] < row_end_) {
        f[idx[b] - row_begin_] += Fe[b];
      } else {
        other_rows.push_back(idx[b]);
        other_values.push_back(Fe[b]);
      }
    }
  }
  CELLFSI_PETSC(VecRestoreArray(F, &f));
  CELLFSI_PETSC(VecSetValues(F, static_cast<PetscInt>(other_rows.size()), other_rows.data(),
                             other_values.data(), ADD_VALUES));
}

namespace {

/// interior_residual_batched's fields at a block's points (x[q * m + e]) and the residual's point values it
/// fills: r (the value's), rg[i][j] (the gradient's; rows j >= D set to 0) and rq (the continuity's).
struct BlockPointFields {
  int nq = 0, m = 0;
  const double* weight = nullptr;
  const double *v[3] = {}, *a[3] = {}, *dv[3][3] = {}, *p = nullptr, *nu = nullptr;
  double nu0 = 0, convection = 1, g[3] = {0, 0, 0};
  double *r[3] = {}, *rg[3][3] = {}, *rq = nullptr;
};

/// The point values with the dimension fixed, so that the loop over the block's elements vectorises (with
/// run-time loops over the components it was half of the residual's time; perf).
template <int D>
void block_point_residual(const BlockPointFields& f) {
  CELLFSI_PETSC(PetscLogFlops(f.nq * f.m * (D * (6.0 * D + 5) + 1)));
  for (int q = 0; q < f.nq; ++q) {
    const double w = f.weight[q];
    const size_t k0 = static_cast<size_t>(q) * f.m;
    for (int e = 0; e < f.m; ++e) {
      const size_t k = k0 + e;
      double v[D], dv[D][D];
      for (int c = 0; c < D; ++c) {
        v[c] = f.v[c][k];
        for (int j = 0; j < D; ++j) dv[c][j] = f.dv[c][j][k];
      }
      const double p = f.p[k], nu = f.nu ? f.nu[k] : f.nu0;
      double rq = 0;
      for (int i = 0; i < D; ++i) {
        double conv = 0;
        for (int l = 0; l < D; ++l) conv += v[l] * dv[i][l];
        f.r[i][k] = w * (f.a[i][k] + f.convection * conv - f.g[i]);
        for (int j = 0; j < D; ++j) f.rg[i][j][k] = w * (nu * (dv[i][j] + dv[j][i]) - (i == j ? p : 0.0));
        for (int j = D; j < 3; ++j) f.rg[i][j][k] = 0.0;
        rq += dv[i][i];
      }
      f.rq[k] = w * rq;
    }
  }
}

}  // namespace

void DivConformingFluid::interior_residual_batched(const Levels& lv, Vec F) const {
  // interior_residual_sized's sums for a uniform body force, over blocks of elements that share their basis
  // (basis_class), by sum factorisation (dc_sum_factorization.hpp): per velocity component the block's values
  // and gradients at the points, one direction at a time, and the residual's point values tested the same way
  // back; the pressure (and the viscosity field) likewise with the pressure's factors. Measured on the 3D
  // compound capsule at 64^3, k' = 2, two ranks: the elements' terms 0.37 s per residual, 0.65 s with one
  // GEMM of the whole element basis per block (docs/notes/2026-11-29-dc-step-sum-factorisation.md).
  const int D = space_.dim();
  const bool field = lv.viscosity_field && !nu_field_.empty();
  const Vec3 g = lv.g ? lv.g(Vec3::Zero()) : Vec3(Vec3::Zero());
  constexpr int kBlock = 128;
  // Per component c: coefficients U (values at t_{n+alpha_f}), A (rates), the fields at the points (value Y,
  // gradient Yg[j], rate Ya) and the residual's point values (R for the value, Rg[j] for the gradient).
  std::vector<double> U[3], A[3], Y[3], Ya[3], Yg[3][3], R[3], Rg[3][3], P, Yp, Nu, Ynu, Rq, Fc, scratch;
  std::vector<PetscInt> other_rows;
  std::vector<double> other_values;
  PetscScalar* f;
  CELLFSI_PETSC(VecGetArray(F, &f));
  auto add_row = [&](int natural, double value) {
    const PetscInt r = petsc_index_[natural];
    if (r >= row_begin_ && r < row_end_) {
      f[r - row_begin_] += value;
    } else {
      other_rows.push_back(r);
      other_values.push_back(value);
    }
  };
  for (const std::vector<int>& members : elements_by_class()) {
    if (members.empty()) continue;
    const ElementBasis& eb = element_basis(members.front());
    const Index3 ei = space_.element_multi_index(members.front());
    const TensorRule rule = space_.element_rule(ei, n_gauss());
    ComponentFactors fac[4];
    for (int c = 0; c <= D; ++c) fac[c] = component_factors(space_, c, ei, rule);
    const int nq = eb.n_points, np = eb.comp[D].n;
    if (fac[0].n_points() != nq)
      throw std::logic_error("interior_residual_batched: the factors' rule is not the basis'");
    int nv[3] = {0, 0, 0}, off[4] = {0, 0, 0, 0};
    for (int c = 0; c < D; ++c) nv[c] = eb.comp[c].n, off[c + 1] = off[c] + nv[c];
    for (size_t first = 0; first < members.size(); first += kBlock) {
      const int m = static_cast<int>(std::min<size_t>(kBlock, members.size() - first));
      const size_t mq = static_cast<size_t>(nq) * m;
      // Gather the block's coefficients (function a of element e at a m + e).
      const int* block = members.data() + first;
      for (int c = 0; c < D; ++c) {
        gather_block(block, m, off[c], nv[c], lv.v.data(), 0, U[c]);
        gather_block(block, m, off[c], nv[c], lv.a.data(), 0, A[c]);
      }
      gather_block(block, m, off[D], np, lv.v.data(), 0, P);
      if (field) gather_block(block, m, off[D], np, nu_field_.data(), space_.offset(D), Nu);
      for (int c = 0; c < D; ++c) {
        Y[c].resize(mq);
        Ya[c].resize(mq);
        for (auto& y : Yg[c]) y.resize(mq);
        const std::array<double*, 3> grad{Yg[c][0].data(), Yg[c][1].data(), Yg[c][2].data()};
        sum_factorized_values(fac[c], m, U[c].data(), Y[c].data(), &grad, scratch);
        sum_factorized_values(fac[c], m, A[c].data(), Ya[c].data(), nullptr, scratch);
      }
      Yp.resize(mq);
      sum_factorized_values(fac[D], m, P.data(), Yp.data(), nullptr, scratch);
      if (field) {
        Ynu.resize(mq);
        sum_factorized_values(fac[D], m, Nu.data(), Ynu.data(), nullptr, scratch);
      }
      // The residual's point values (interior_residual_sized's r0, r1, rq, times the weight).
      for (int c = 0; c < D; ++c) {
        R[c].resize(mq);
        for (int j = 0; j < 3; ++j) Rg[c][j].resize(mq);
      }
      Rq.resize(mq);
      BlockPointFields pf;
      pf.nq = nq, pf.m = m;
      pf.weight = eb.weight.data();
      pf.p = Yp.data(), pf.nu = field ? Ynu.data() : nullptr, pf.nu0 = lv.nu;
      pf.convection = lv.convection;
      pf.rq = Rq.data();
      for (int c = 0; c < D; ++c) {
        pf.g[c] = g[c];
        pf.v[c] = Y[c].data(), pf.a[c] = Ya[c].data(), pf.r[c] = R[c].data();
        for (int j = 0; j < 3; ++j) pf.dv[c][j] = Yg[c][j].data(), pf.rg[c][j] = Rg[c][j].data();
      }
      if (D == 3)
        block_point_residual<3>(pf);
      else
        block_point_residual<2>(pf);
      // Tested against the functions and added to the elements' rows.
      for (int c = 0; c <= D; ++c) {
        const int n = c < D ? nv[c] : np;
        Fc.resize(static_cast<size_t>(n) * m);
        if (c < D) {
          const std::array<const double*, 3> rg{Rg[c][0].data(), Rg[c][1].data(), Rg[c][2].data()};
          sum_factorized_test(fac[c], m, R[c].data(), &rg, Fc.data(), scratch);
        } else {
          sum_factorized_test(fac[c], m, Rq.data(), nullptr, Fc.data(), scratch);
        }
        for (int e = 0; e < m; ++e) {
          const int* idx =
              element_unknowns_.data() + static_cast<size_t>(members[first + e] - elem_begin_) * n_local_;
          for (int b = 0; b < n; ++b) add_row(idx[off[c] + b], Fc[static_cast<size_t>(b) * m + e]);
        }
      }
    }
  }
  CELLFSI_PETSC(VecRestoreArray(F, &f));
  CELLFSI_PETSC(VecSetValues(F, static_cast<PetscInt>(other_rows.size()), other_rows.data(),
                             other_values.data(), ADD_VALUES));
}

void DivConformingFluid::immersed_residual(const Levels& lv, Vec F) const {
  // The points' residual by sum factorisation at each point (dc_sum_factorization.hpp: point_value,
  // point_test): the element's coefficients gathered once per element, the fields and the test sums
  // direction by direction from the point's univariate factors; velocity rows only (the points have no
  // continuity term).
  const int D = space_.dim();
  const bool field = lv.viscosity_field && !nu_field_.empty();
  ImmersedParameters prm;
  prm.dim = D;
  prm.convection = lv.convection;
  PointFactors pf;
  int off[5] = {0, 0, 0, 0, 0};  // the components' first local unknowns, and the end
  for (int c = 0; c <= D; ++c) {
    int n = 1;
    for (int d = 0; d < D; ++d) n *= space_.knots(c, d).degree() + 1;
    off[c + 1] = off[c] + n;
  }
  const int n_vel = off[D], n_p = off[D + 1] - off[D];
  std::vector<double> ue(n_vel), ae(n_vel), nue(n_p), Fe(n_vel);
  std::vector<int> other_unknowns;
  std::vector<PetscInt> idx(n_vel);
  int current = -1;
  auto flush = [&] {
    if (current >= 0) CELLFSI_PETSC(VecSetValues(F, n_vel, idx.data(), Fe.data(), ADD_VALUES));
  };
  for (const ImmersedAt& p : immersed_) {
    if (p.element != current) {
      flush();
      current = p.element;
      const int* u = unknowns_of(p.element, other_unknowns);
      for (int a = 0; a < n_vel; ++a) {
        ue[a] = lv.v[u[a]];
        ae[a] = lv.a[u[a]];
        idx[a] = petsc_index_[u[a]];
        Fe[a] = 0.0;
      }
      if (field)
        for (int a = 0; a < n_p; ++a) nue[a] = nu_field_[u[n_vel + a] - space_.offset(D)];
    }
    point_factors(space_, space_.element_multi_index(p.element), p.x, pf);
    PointState st;
    for (int i = 0; i < D; ++i) {
      double g[3];
      st.v[i] = point_value(pf, i, ue.data() + off[i], g);
      st.a[i] = point_value(pf, i, ae.data() + off[i], nullptr);
      for (int j = 0; j < D; ++j) st.dv[i][j] = g[j];
    }
    prm.nu = field ? point_value(pf, D, nue.data(), nullptr) : lv.nu;
    const Vec3 g = lv.g ? lv.g(p.x) : Vec3(Vec3::Zero());
    for (int i = 0; i < 3; ++i) prm.g[i] = g[i];
    const PointResidual r = dc_immersed_residual(st, prm, p.data);
    const double w = p.data.weight;
    for (int i = 0; i < D; ++i) {
      const double rg[3] = {w * r.r1[i][0], w * r.r1[i][1], D == 3 ? w * r.r1[i][2] : 0.0};
      point_test(pf, i, w * r.r0[i], rg, Fe.data() + off[i]);
    }
  }
  flush();
}

void DivConformingFluid::assemble_immersed(const Levels& lv, Vec F, Mat J,
                                           const std::vector<PetscInt>* rows) const {
  if (!rows) rows = &petsc_index_;
  if (!J && !space_.is_mapped()) return immersed_residual(lv, F);
  const int D = space_.dim();
  ElementBasis eb;
  std::vector<double> Fe, Ke;
  std::vector<PetscInt> idx;
  TangentAccumulator tangent;
  int n_loc = 0;
  int n_vel = 0;  // the velocity unknowns, first in idx: the points' tangent has no pressure row or column
  auto flush = [&] {
    if (idx.empty()) return;
    if (F) CELLFSI_PETSC(VecSetValues(F, n_loc, idx.data(), Fe.data(), ADD_VALUES));
    if (J) {
      tangent.flush();
      CELLFSI_PETSC(MatSetValues(J, n_vel, idx.data(), n_vel, idx.data(), Ke.data(), ADD_VALUES));
    }
    idx.clear();
  };
  const bool field = lv.viscosity_field && !nu_field_.empty();
  ImmersedParameters prm;
  prm.dim = D;
  prm.convection = lv.convection;
  int current = -1;
  TensorRule rule;  // (one point; kept, so that the loop allocates nothing)
  for (const ImmersedAt& p : immersed_) {
    const Index3 ei = space_.element_multi_index(p.element);
    for (int d = 0; d < 3; ++d) {
      rule.points[d].assign(1, d < D ? p.x[d] : 0.0);
      rule.weights[d].assign(1, 1.0);
    }
    space_.evaluate(ei, rule, eb, p.element != current);
    if (p.element != current) {
      flush();
      current = p.element;
      n_loc = 0;
      for (int c = 0; c <= D; ++c) n_loc += eb.comp[c].n;
      n_vel = n_loc - eb.comp[D].n;
      Fe.assign(n_loc, 0.0);
      if (J) {
        Ke.assign(static_cast<size_t>(n_vel) * n_vel, 0.0);
        tangent.start(eb, D, &Ke, true);
      }
      idx = local_indices(eb, D);
      for (PetscInt& g : idx) g = (*rows)[g];
    }
    PointState st;
    const auto pv = DivConformingSpace::interpolate(eb, 0, D, lv.v.data());
    const auto pa = DivConformingSpace::interpolate_velocity(eb, 0, D, lv.a.data());
    for (int i = 0; i < D; ++i) {
      st.v[i] = pv.v[i];
      st.a[i] = pa[i];
      for (int j = 0; j < D; ++j) st.dv[i][j] = pv.grad[i][j];
    }
    prm.nu = lv.nu;
    if (field) {
      const ComponentBasis& cb = eb.comp[D];
      prm.nu = 0;
      for (int a = 0; a < cb.n; ++a) prm.nu += nu_field_[cb.index[a] - space_.offset(D)] * cb.value[a];
    }
    const Vec3 g = lv.g ? lv.g(eb.x[0]) : Vec3(Vec3::Zero());
    for (int i = 0; i < 3; ++i) prm.g[i] = g[i];
    // (a mapped space: the point's measure is its own weight, not J dxi; the test side through the map)
    const PiolaPoint* map = eb.piola.empty() ? nullptr : &eb.piola[0];
    if (F) {
      const PointResidual r = dc_immersed_residual(st, prm, p.data);
      add_point_residual(eb, 0, D, p.data.weight, map ? piola_residual(*map, r) : r, Fe);
    }
    if (!J) continue;
    PointTangent t;
    if (solid_apart_ && p.data.solid_begin >= 0) {  // its stiffness is solid_blocks()'
      ImmersedPoint without = p.data;
      without.stiffness_time = 0;
      without.stiffness_viscosity = 0;
      t = dc_immersed_tangent(st, prm, without);
    } else {
      t = dc_immersed_tangent(st, prm, p.data);
    }
    tangent.add(eb, 0, p.data.weight, map ? piola_tangent(*map, t) : t, lv.dv_dU, lv.da_dU);
  }
  flush();
}

std::vector<DivConformingFluid::SolidBlock> DivConformingFluid::solid_blocks(
    const std::vector<int>& column, const std::vector<double>& grad) const {
  if (space_.is_mapped())
    throw std::logic_error("DivConformingFluid::solid_blocks: not written for a mapped space");
  // Points of one body element inside one fluid element share their columns (they come in the body's
  // quadrature order, kept by set_immersed_points' stable sort): for each such group and velocity
  // component i the block's rows of i gain one GEMM, (w dN_a/dx_j)_{a, (p, j)} times
  // (sum_l X^p_ijkl dN_r/dx_l)_{(p, j), (k, r)}, X the points' stiffness (c + the stress terms).
  static constexpr int voigt[3][3] = {{0, 5, 4}, {5, 1, 3}, {4, 3, 2}};
  const int D = space_.dim();
  std::vector<char> fixed(space_.n_dofs(), 0);
  for (int r : fixed_rows_) fixed[r] = 1;
  auto uses = [](const ImmersedPoint& ip) { return ip.solid_begin >= 0 && ip.stiffness_time > 0; };
  auto same_columns = [&](const ImmersedPoint& a, const ImmersedPoint& b) {
    return a.solid_end - a.solid_begin == b.solid_end - b.solid_begin &&
           std::equal(column.begin() + a.solid_begin, column.begin() + a.solid_end,
                      column.begin() + b.solid_begin);
  };
  std::vector<SolidBlock> out;
  ElementBasis eb;
  TensorRule rule;
  std::vector<int> where;                       // column -> its place in the block's columns (-1: none)
  std::vector<double> left[3], right[3], prod;  // a group's GEMM operands per component, and its product
  size_t first = 0;
  while (first < immersed_.size()) {
    const int e = immersed_[first].element;
    size_t last = first;
    while (last < immersed_.size() && immersed_[last].element == e) ++last;
    SolidBlock b;  // its columns in the order met, `where` marking those taken
    for (size_t i = first; i < last; ++i) {
      const ImmersedPoint& ip = immersed_[i].data;
      if (!uses(ip)) continue;
      for (int k = ip.solid_begin; k < ip.solid_end; ++k)
        for (int c = 0; c < D; ++c) {
          const int col = column[k] + c;
          if (static_cast<int>(where.size()) <= col) where.resize(col + 1, -1);
          if (where[col] >= 0) continue;
          where[col] = static_cast<int>(b.cols.size());
          b.cols.push_back(col);
        }
    }
    if (b.cols.empty()) {
      first = last;
      continue;
    }
    const int n_cols = static_cast<int>(b.cols.size());
    int off[4] = {0, 0, 0, 0};
    bool new_element = true;
    size_t g0 = first;
    while (g0 < last) {
      if (!uses(immersed_[g0].data)) {
        ++g0;
        continue;
      }
      size_t g1 = g0 + 1;
      while (g1 < last && uses(immersed_[g1].data) && same_columns(immersed_[g0].data, immersed_[g1].data))
        ++g1;
      const int P = static_cast<int>(g1 - g0), K = D * P;
      const ImmersedPoint& head = immersed_[g0].data;
      const int n_e = head.solid_end - head.solid_begin, n_c = D * n_e;
      for (int p = 0; p < P; ++p) {
        const ImmersedAt& pt = immersed_[g0 + p];
        const ImmersedPoint& ip = pt.data;
        for (int d = 0; d < 3; ++d) {
          rule.points[d].assign(1, d < D ? pt.x[d] : 0.0);
          rule.weights[d].assign(1, 1.0);
        }
        space_.evaluate(space_.element_multi_index(e), rule, eb, new_element);
        if (new_element) {
          for (int c = 0; c < D; ++c) off[c + 1] = off[c] + eb.comp[c].n;
          const std::vector<PetscInt> idx = local_indices(eb, D);
          b.rows.resize(off[D]);
          for (int r = 0; r < off[D]; ++r) b.rows[r] = fixed[idx[r]] ? -1 : petsc_index_[idx[r]];
          b.values.assign(static_cast<size_t>(off[D]) * n_cols, 0.0);
          new_element = false;
        }
        double c6[6][6];
        for (int r = 0, t = 0; r < 6; ++r)
          for (int q = r; q < 6; ++q, ++t) c6[r][q] = c6[q][r] = ip.stiffness[t];
        for (int i = 0; i < D; ++i) {
          const ComponentBasis& cb = eb.comp[i];
          if (p == 0) {
            left[i].resize(static_cast<size_t>(cb.n) * K);
            right[i].resize(static_cast<size_t>(K) * n_c);
          }
          // left_i (n_i x K, column-major): w dN_a / dx_j in column (p, j).
          for (int j = 0; j < D; ++j)
            for (int a = 0; a < cb.n; ++a)
              left[i][static_cast<size_t>(p * D + j) * cb.n + a] =
                  ip.weight * cb.grad[3 * static_cast<size_t>(a) + j];
          // right_i (K x n_c, column-major): row (p, j), column (k, r).
          for (int j = 0; j < D; ++j)
            for (int k = 0; k < D; ++k) {
              double X[3];
              for (int l = 0; l < D; ++l) {
                X[l] = c6[voigt[i][j]][voigt[k][l]];
                if (j == k) X[l] += ip.stress[i][l];
                if (i == k) X[l] += ip.stress[l][j];
              }
              for (int r = 0; r < n_e; ++r) {
                const double* g = grad.data() + 3 * static_cast<size_t>(ip.solid_begin + r);
                double sum = 0;
                for (int l = 0; l < D; ++l) sum += X[l] * g[l];
                right[i][static_cast<size_t>(k * n_e + r) * K + p * D + j] = sum;
              }
            }
        }
      }
      for (int i = 0; i < D; ++i) {
        const PetscBLASInt m = eb.comp[i].n, n = n_c, kk = K;
        const double one = 1.0, zero = 0.0;
        prod.resize(static_cast<size_t>(m) * n);
        BLASgemm_("N", "N", &m, &n, &kk, &one, left[i].data(), &m, right[i].data(), &kk, &zero, prod.data(),
                  &m);
        // (-log_view's counts: the product, and the right operand: n_c sums of D terms per point and row j)
        CELLFSI_PETSC(PetscLogFlops(2.0 * m * n * kk + 2.0 * P * D * D * n_c));
        for (int k = 0; k < D; ++k)
          for (int r = 0; r < n_e; ++r) {
            const int col = where[column[head.solid_begin + r] + k];
            const double* src = prod.data() + static_cast<size_t>(k * n_e + r) * m;
            for (int a = 0; a < m; ++a) b.values[static_cast<size_t>(off[i] + a) * n_cols + col] += src[a];
          }
      }
      g0 = g1;
    }
    for (int c : b.cols) where[c] = -1;
    out.push_back(std::move(b));
    first = last;
  }
  return out;
}

void DivConformingFluid::set_immersed_points(const std::vector<ImmersedAt>& points) {
  // Sorted by an index permutation, then copied once into immersed_'s kept storage: a point is about 800
  // bytes, and new vectors of them at every coupling iteration (3 x 110 MB per rank at 64^3) came back from
  // the kernel as fresh pages to fault in and clear.
  point_order_.clear();
  for (std::size_t i = 0; i < points.size(); ++i) point_order_.push_back(static_cast<int>(i));
  std::stable_sort(point_order_.begin(), point_order_.end(),
                   [&](int a, int b) { return points[a].element < points[b].element; });
  immersed_.clear();
  immersed_.reserve(point_order_.size());
  for (int i : point_order_) immersed_.push_back(points[i]);
}

void DivConformingFluid::begin_step() {
  Un_ = U_;
  Udotn_ = Udot_;
  for (GatherPart& g : parts_) g.elements.clear();  // (gather_part's sets: the next call makes them anew)
}

void DivConformingFluid::step_residual(const std::vector<double>& U, Vec F, bool pin_pressure,
                                       std::optional<int> part) {
  if (Un_.empty()) throw std::logic_error("DivConformingFluid::step_residual before begin_step");
  if (part)
    assemble(part_levels(U, *part), F, nullptr);
  else
    assemble(step_levels(U, Un_, Udotn_), F, nullptr);
  PetscScalar* f;
  CELLFSI_PETSC(VecGetArray(F, &f));
  const PetscInt pin = petsc_index_[space_.offset(space_.dim())];
  for (PetscInt r : owned_fixed_)
    if (pin_pressure || r != pin) f[r - row_begin_] = 0.0;
  CELLFSI_PETSC(VecRestoreArray(F, &f));
}

DivConformingFluid::Levels DivConformingFluid::iterate_levels(const std::vector<double>& U) const {
  const bool started = !Un_.empty();
  return step_levels(U, started ? Un_ : U_, started ? Udotn_ : Udot_);
}

void DivConformingFluid::zero_fixed_rows(Mat J, bool pin_pressure, double diagonal,
                                         const RowSubset* subset) const {
  std::vector<PetscInt> rows;
  const PetscInt pin = petsc_index_[space_.offset(space_.dim())];
  for (size_t k = 0; k < owned_fixed_.size(); ++k) {
    const PetscInt r = owned_fixed_[k];
    if ((pin_pressure || r != pin) && (!subset || subset->rows[owned_fixed_natural_[k]])) rows.push_back(r);
  }
  CELLFSI_PETSC(MatZeroRows(J, static_cast<PetscInt>(rows.size()), rows.data(), diagonal, nullptr, nullptr));
}

void DivConformingFluid::step_tangent(const std::vector<double>& U, Mat J, bool with_immersed,
                                      bool pin_pressure) {
  Levels lv = iterate_levels(U);
  if (!with_immersed) lv.viscosity_field = false;
  assemble(lv, F_, J, with_immersed);
  zero_fixed_rows(J, pin_pressure, 1.0);
}

void DivConformingFluid::bulk_tangent_of_mean(const std::vector<double>& U, Mat J) {
  if (space_
          .is_mapped())  // (the mean along x of a curved domain's flow is no translation-invariant operator)
    throw std::logic_error(
        "DivConformingFluid::bulk_tangent_of_mean: a box's operator, not a mapped space's");
  const bool started = !Un_.empty();
  std::vector<double> u = U, un = started ? Un_ : U_, rate = started ? Udotn_ : Udot_;
  for (std::vector<double>* v : {&u, &un, &rate}) space_.average_periodic(*v);
  Levels lv = step_levels(u, un, rate);
  lv.viscosity_field = false;
  assemble(lv, F_, J, false);
  zero_fixed_rows(J, false, 1.0);
}

Mat DivConformingFluid::bulk_stencil_tangent(const std::vector<double>& U) {
  if (space_.is_mapped())
    throw std::logic_error(
        "DivConformingFluid::bulk_stencil_tangent: a box's operator, not a mapped space's");
  // The rows of the columns (x index i, z index l) below: (0, 0) for the stencil, two more for the check.
  const int D = space_.dim(), nx = space_.n_elements(0), nz = D == 3 ? space_.n_elements(2) : 1;
  const std::array<std::array<int, 2>, 3> columns{{{0, 0}, {nx / 2, nz / 2}, {nx / 3, (2 * nz) / 3}}};
  RowSubset subset;
  subset.rows.assign(space_.n_dofs(), 0);
  for (int c = 0; c <= D; ++c) {
    const int ny = space_.n_basis(c, 1), first = space_.offset(c);
    const int count = space_.n_basis(c);
    for (int local = 0; local < count; ++local) {
      const int i = local % space_.n_basis(c, 0), l = local / (space_.n_basis(c, 0) * ny);
      for (const auto& col : columns)
        if (i == col[0] && l == col[1]) subset.rows[first + local] = 1;
    }
  }
  Mat S = create_matrix(&subset.rows, &subset.elements);
  const bool started = !Un_.empty();
  std::vector<double> u = U, un = started ? Un_ : U_, rate = started ? Udotn_ : Udot_;
  for (std::vector<double>* v : {&u, &un, &rate}) space_.average_periodic(*v);
  Levels lv = step_levels(u, un, rate);
  lv.viscosity_field = false;
  assemble(lv, F_, S, false, &subset);
  zero_fixed_rows(S, false, 1.0, &subset);
  return S;
}

void DivConformingFluid::step_tangent_from(Mat bulk, const std::vector<double>& U, Mat J, bool pin_pressure) {
  const Levels lv = iterate_levels(U);
  CELLFSI_PETSC(MatCopy(bulk, J, SAME_NONZERO_PATTERN));
  assemble_immersed(lv, nullptr, J);
  CELLFSI_PETSC(MatAssemblyBegin(J, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(J, MAT_FINAL_ASSEMBLY));
  zero_fixed_rows(J, pin_pressure, 1.0);
}

void DivConformingFluid::immersed_tangent(const std::vector<double>& U, const ImmersedMatrix& C,
                                          std::optional<int> part) {
  Levels whole;
  if (!part) whole = iterate_levels(U);
  assemble_immersed(part ? part_levels(U, *part) : whole, nullptr, C.C, &C.row_of);
  CELLFSI_PETSC(MatAssemblyBegin(C.C, MAT_FINAL_ASSEMBLY));
  CELLFSI_PETSC(MatAssemblyEnd(C.C, MAT_FINAL_ASSEMBLY));
  // The fixed rows in S that this rank owns there (the pressure pin is no velocity unknown: not in S).
  PetscInt begin = 0, end = 0;
  CELLFSI_PETSC(MatGetOwnershipRange(C.C, &begin, &end));
  std::vector<PetscInt> rows;
  for (int g : fixed_rows_) {
    const PetscInt r = C.row_of[g];
    if (r >= begin && r < end) rows.push_back(r);
  }
  CELLFSI_PETSC(MatZeroRows(C.C, static_cast<PetscInt>(rows.size()), rows.data(), 0.0, nullptr, nullptr));
}

std::vector<int> DivConformingFluid::immersed_elements() const {
  std::vector<int> e;
  for (const ImmersedAt& p : immersed_)  // sorted by element (set_immersed_points)
    if (e.empty() || e.back() != p.element) e.push_back(p.element);
  return e;
}

DivConformingFluid::ImmersedMatrix DivConformingFluid::create_immersed_matrix() const {
  // The elements with points on every rank, and each one's unknowns (natural numbering).
  const std::vector<int> mine = immersed_elements();
  int size = 1, rank = 0;
  CELLFSI_PETSC(MPI_Comm_size(comm_, &size));
  CELLFSI_PETSC(MPI_Comm_rank(comm_, &rank));
  int n_mine = static_cast<int>(mine.size());
  std::vector<int> counts(size), displs(size + 1, 0);
  CELLFSI_PETSC(MPI_Allgather(&n_mine, 1, MPI_INT, counts.data(), 1, MPI_INT, comm_));
  for (int r = 0; r < size; ++r) displs[r + 1] = displs[r] + counts[r];
  std::vector<int> all(displs[size]);
  CELLFSI_PETSC(
      MPI_Allgatherv(mine.data(), n_mine, MPI_INT, all.data(), counts.data(), displs.data(), MPI_INT, comm_));
  const int D = space_.dim();
  // An element's velocity unknowns (first in its local numbering): the points' tangent has no pressure row or
  // column (assemble_immersed).
  // (Component i: degree k' + 1 along x_i, k' along the others.)
  const int n_velocity = D * (space_.degree() + 2) * static_cast<int>(std::pow(space_.degree() + 1, D - 1));
  // (-log_view's count: an estimate of the loops' operations, in units of one unknown visited in the
  // pattern's count below, weighted by timers at 64^3 (3400 elements, S 33 000 rows): an element of another
  // rank's evaluated, 15 per unknown; S's sort, 4 per comparison; a row's element appended, 18. Every rank
  // goes over every element with points and sorts S: 7 of 40 ms on one rank, the part that does not divide.)
  double operations = 0;
  std::vector<std::vector<int>> unknowns(all.size());
  ElementBasis eb;
  for (size_t k = 0; k < all.size(); ++k) {
    const int e = all[k];
    if (e >= elem_begin_ && e < elem_end_) {
      const auto first = element_unknowns_.begin() + static_cast<std::ptrdiff_t>(e - elem_begin_) * n_local_;
      unknowns[k].assign(first, first + n_velocity);
      operations += n_velocity;
    } else {
      const Index3 ei = space_.element_multi_index(e);
      space_.evaluate(ei, space_.element_rule(ei, 1), eb);  // indices only
      const std::vector<PetscInt> idx = local_indices(eb, D);
      unknowns[k].assign(idx.begin(), idx.begin() + n_velocity);
      operations += 15.0 * n_velocity;
    }
  }
  // S: those unknowns in PETSc order (a rank's run of S then lies mostly in its own rows of the fluid).
  ImmersedMatrix m;
  std::vector<std::pair<PetscInt, int>> in_s;  // (PETSc row, natural)
  m.row_of.assign(space_.n_dofs(), -1);
  for (const std::vector<int>& us : unknowns)
    for (int u : us)
      if (m.row_of[u] < 0) m.row_of[u] = 0, in_s.emplace_back(petsc_index_[u], u);
  std::sort(in_s.begin(), in_s.end());
  const auto n_s = static_cast<PetscInt>(in_s.size());
  operations += 2.0 * n_velocity * all.size() + 4.0 * n_s * std::log2(std::max<double>(n_s, 2));
  for (PetscInt i = 0; i < n_s; ++i) m.row_of[in_s[i].second] = i;
  const auto s_begin = static_cast<PetscInt>(static_cast<std::int64_t>(n_s) * rank / size),
             s_end = static_cast<PetscInt>(static_cast<std::int64_t>(n_s) * (rank + 1) / size);
  for (PetscInt i = s_begin; i < s_end; ++i) m.fluid_rows.push_back(in_s[i].first);
  // Each owned row's elements, then its distinct columns (an element adds its whole block, as its tangent).
  const PetscInt n_own = s_end - s_begin;
  std::vector<std::vector<int>> row_elements(n_own);
  for (size_t k = 0; k < all.size(); ++k)
    for (int u : unknowns[k]) {
      const PetscInt r = m.row_of[u];
      if (r >= s_begin && r < s_end) row_elements[r - s_begin].push_back(static_cast<int>(k));
    }
  std::vector<PetscInt> d_nnz(n_own, 0), o_nnz(n_own, 0);
  std::vector<PetscInt> stamp(space_.n_dofs(), -1);
  for (PetscInt i = 0; i < n_own; ++i)
    for (int k : row_elements[i])
      for (int u : unknowns[k]) {
        if (stamp[u] == i) continue;
        stamp[u] = i;
        const PetscInt c = m.row_of[u];
        (c >= s_begin && c < s_end ? d_nnz : o_nnz)[i] += 1;
      }
  for (PetscInt i = 0; i < n_own; ++i)
    operations += static_cast<double>(row_elements[i].size()) * (18.0 + n_velocity);
  CELLFSI_PETSC(PetscLogFlops(operations));
  try {  // (a failure leaves nothing made behind)
    CELLFSI_PETSC(MatCreateAIJ(comm_, n_own, n_own, n_s, n_s, 0, d_nnz.data(), 0, o_nnz.data(), &m.C));
    CELLFSI_PETSC(MatSetOption(m.C, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_TRUE));
    // The fixed rows are zeroed after each assembly (immersed_tangent): without this, MatZeroRows drops their
    // entries and the next assembly on the same pattern (the points' elements unchanged) finds no room for
    // them.
    CELLFSI_PETSC(MatSetOption(m.C, MAT_KEEP_NONZERO_PATTERN, PETSC_TRUE));
    CELLFSI_PETSC(MatCreateVecs(m.C, &m.in, &m.out));
    m.to_s = make_row_scatter(x_, m.fluid_rows, m.in);
  } catch (...) {
    m.destroy();
    throw;
  }
  return m;
}

void DivConformingFluid::ImmersedMatrix::multiply_add(Vec x, Vec y) const {
  CELLFSI_PETSC(VecScatterBegin(to_s, x, in, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(VecScatterEnd(to_s, x, in, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(MatMult(C, in, out));
  CELLFSI_PETSC(VecScatterBegin(to_s, out, y, ADD_VALUES, SCATTER_REVERSE));
  CELLFSI_PETSC(VecScatterEnd(to_s, out, y, ADD_VALUES, SCATTER_REVERSE));
}

void DivConformingFluid::ImmersedMatrix::destroy() {
  MatDestroy(&C);
  VecScatterDestroy(&to_s);
  VecDestroy(&in);
  VecDestroy(&out);
}

void DivConformingFluid::end_step(const std::vector<double>& U) {
  if (Un_.empty()) throw std::logic_error("DivConformingFluid::end_step before begin_step");
  const int nv = space_.n_velocity();
  for (int i = 0; i < nv; ++i) Udot_[i] = alpha_.rate(U[i], Un_[i], Udotn_[i]);
  U_ = U;
  shift_pressure_to_zero_mean(U_);
  ++steps_;
  time_ = steps_ * opt_.dt;
  div_history_.push_back(divergence_ratio());
  Un_.clear();
  Udotn_.clear();
}

std::vector<DivConformingFluid::StepSample> DivConformingFluid::sample_step(const std::vector<double>& U,
                                                                            const std::vector<int>& elements,
                                                                            const std::vector<Vec3>& x,
                                                                            std::optional<int> part) const {
  const int D = space_.dim();
  Levels whole;
  if (!part) whole = iterate_levels(U);
  const Levels& lv = part ? part_levels(U, *part) : whole;
  std::vector<StepSample> out(x.size());
  ElementBasis eb;
  TensorRule rule;  // (one point; kept, so that the loop allocates nothing)
  for (size_t i = 0; i < x.size(); ++i) {
    for (int d = 0; d < 3; ++d) {
      rule.points[d].assign(1, d < D ? x[i][d] : 0.0);
      rule.weights[d].assign(1, 1.0);
    }
    space_.evaluate(space_.element_multi_index(elements[i]), rule, eb,
                    i == 0 || elements[i] != elements[i - 1]);
    const auto pv = DivConformingSpace::interpolate(eb, 0, D, lv.v.data());
    const auto pa = DivConformingSpace::interpolate_velocity(eb, 0, D, lv.a.data());
    // (-log_view's counts: the sums of the velocity, its gradient and the acceleration, 2 per function and
    // value; the basis' own evaluation not counted)
    double sums = 0;
    for (int c = 0; c < D; ++c) sums += 2.0 * eb.comp[c].n * (2 + D);
    CELLFSI_PETSC(PetscLogFlops(sums));
    for (int a = 0; a < D; ++a) {
      out[i].v[a] = pv.v[a];
      out[i].a[a] = pa[a];
      for (int b = 0; b < D; ++b) out[i].grad_v(a, b) = pv.grad[a][b];
    }
  }
  return out;
}

Vec DivConformingFluid::create_vector() const {
  Vec v;
  CELLFSI_PETSC(VecDuplicate(F_, &v));
  return v;
}

void DivConformingFluid::gather(Vec X, std::vector<double>& U) const {
  const int n = space_.n_dofs();
  CELLFSI_PETSC(VecScatterBegin(to_all_, X, x_all_, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(VecScatterEnd(to_all_, X, x_all_, INSERT_VALUES, SCATTER_FORWARD));
  const PetscScalar* xp;
  CELLFSI_PETSC(VecGetArrayRead(x_all_, &xp));
  U.resize(n);
  for (int i = 0; i < n; ++i) U[i] = xp[petsc_index_[i]];
  CELLFSI_PETSC(VecRestoreArrayRead(x_all_, &xp));
  // (-log_view's counts: every rank copies and reorders every unknown, which does not divide; 5 operations an
  // unknown, the loops' time at 64^3 on one rank, 1.6 ms a call, against the linear solves' 3.9 Gflop/s)
  CELLFSI_PETSC(PetscLogFlops(5.0 * n));
}

void DivConformingFluid::UnknownSet::make(Vec X, const std::vector<PetscInt>& petsc_index) {
  destroy();
  std::vector<PetscInt> rows(unknowns.size());
  for (std::size_t k = 0; k < rows.size(); ++k) rows[k] = petsc_index[unknowns[k]];
  CELLFSI_PETSC(VecCreateSeq(PETSC_COMM_SELF, static_cast<PetscInt>(rows.size()), &values));
  IS from = nullptr;
  CELLFSI_PETSC(ISCreateGeneral(PETSC_COMM_SELF, static_cast<PetscInt>(rows.size()), rows.data(),
                                PETSC_COPY_VALUES, &from));
  const PetscErrorCode made = VecScatterCreate(X, from, values, nullptr, &scatter);
  ISDestroy(&from);
  CELLFSI_PETSC(made);
}

void DivConformingFluid::UnknownSet::move(Vec X, std::vector<double>& U) const {
  CELLFSI_PETSC(VecScatterBegin(scatter, X, values, INSERT_VALUES, SCATTER_FORWARD));
  CELLFSI_PETSC(VecScatterEnd(scatter, X, values, INSERT_VALUES, SCATTER_FORWARD));
  const PetscScalar* v;
  CELLFSI_PETSC(VecGetArrayRead(values, &v));
  for (std::size_t k = 0; k < unknowns.size(); ++k) U[static_cast<std::size_t>(unknowns[k])] = v[k];
  CELLFSI_PETSC(VecRestoreArrayRead(values, &v));
  // (-log_view's counts: as gather()'s, 5 operations an unknown moved, here this rank's share)
  CELLFSI_PETSC(PetscLogFlops(5.0 * static_cast<double>(unknowns.size())));
}

void DivConformingFluid::UnknownSet::destroy() {
  VecScatterDestroy(&scatter);
  VecDestroy(&values);
}

void DivConformingFluid::gather_part(Vec X, std::vector<double>& U, int part,
                                     const std::vector<int>& elements, bool move) const {
  if (part != kAssemblyPart && part != kSamplePart)
    throw std::invalid_argument("DivConformingFluid::gather_part: part " + std::to_string(part));
  GatherPart& g = parts_[static_cast<std::size_t>(part)];
  // (-log_view: DcGatherPart, its sets made again DcGatherPartSetUp)
  static const PetscLogEvent event = register_log_event("cellfsi fluid", "DcGatherPart");
  static const PetscLogEvent set_up_event = register_log_event("cellfsi fluid", "DcGatherPartSetUp");
  EventScope ev(event);
  if (part == kAssemblyPart && !own_unknowns_.scatter) {  // (every rank at its first call: collective)
    // (marked, then listed in order: sorting the elements' lists, 18 M entries at 64^3 on 2 ranks, took 1 s)
    std::vector<char> mine(static_cast<std::size_t>(space_.n_dofs()), 0);
    for (int i : element_unknowns_) mine[static_cast<std::size_t>(i)] = 1;
    std::vector<int>& u = own_unknowns_.unknowns;
    u.clear();
    for (std::size_t i = 0; i < mine.size(); ++i)
      if (mine[i]) u.push_back(static_cast<int>(i));
    own_unknowns_.make(X, petsc_index_);
  }
  // The elements' unknowns (outside this rank's elements for kAssemblyPart), made again on every rank when
  // one rank's elements are not all among those its set covers (VecScatterCreate is collective); then it
  // covers these and the ones before, so that points moving to and fro between elements do not make it again
  // at every call (a set over the elements the points visited since the step's start: begin_step resets it).
  int changed = !g.of_elements.scatter ||
                !std::includes(g.elements.begin(), g.elements.end(), elements.begin(), elements.end());
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &changed, 1, MPI_INT, MPI_MAX, comm_));
  if (changed) {
    EventScope set_up(set_up_event);
    std::vector<int> both;
    std::set_union(g.elements.begin(), g.elements.end(), elements.begin(), elements.end(),
                   std::back_inserter(both));
    g.elements = std::move(both);
    std::vector<int>& u = g.of_elements.unknowns;
    u.clear();
    std::vector<int> scratch;
    for (int e : g.elements) {
      if (part == kAssemblyPart && e >= elem_begin_ && e < elem_end_) continue;
      if (e >= elem_begin_ && e < elem_end_) {
        const int* local = unknowns_of(e, scratch);
        u.insert(u.end(), local, local + n_local_);
        continue;
      }
      // (kept per element: about 0.5 kB each in 3D, over the elements a rank's points and samples visit; the
      // size from the evaluation itself, since a rank without elements has no n_local_)
      auto [it, fresh] = foreign_unknowns_.try_emplace(e);
      if (fresh) {
        unknowns_of(e, scratch);
        it->second = scratch;
      }
      u.insert(u.end(), it->second.begin(), it->second.end());
    }
    std::sort(u.begin(), u.end());
    u.erase(std::unique(u.begin(), u.end()), u.end());
    g.of_elements.make(X, petsc_index_);
  }
  if (!move) return;
  U.resize(static_cast<std::size_t>(space_.n_dofs()));
  if (part == kAssemblyPart) own_unknowns_.move(X, U);
  g.of_elements.move(X, U);
}

const DivConformingFluid::Levels& DivConformingFluid::part_levels(const std::vector<double>& U,
                                                                  int part) const {
  GatherPart& g = parts_[static_cast<std::size_t>(part)];
  const bool started = !Un_.empty();
  const std::vector<double>&Un = started ? Un_ : U_, &Udotn = started ? Udotn_ : Udot_;
  const std::size_t n = static_cast<std::size_t>(space_.n_dofs());
  const int nv = space_.n_velocity();
  Levels& lv = g.levels;
  // (NaN where no part has stepped yet, so that a read outside the part shows; the rate's pressure entries 0)
  if (lv.v.size() != n) {
    lv.v.assign(n, std::numeric_limits<double>::quiet_NaN());
    lv.a.assign(n, 0.0);
    std::fill(lv.a.begin(), lv.a.begin() + nv, std::numeric_limits<double>::quiet_NaN());
  }
  auto step = [&](const std::vector<int>& unknowns) {
    for (int i : unknowns) {
      if (i < nv) {
        lv.v[i] = alpha_.value_alpha_f(U[i], Un[i]);
        lv.a[i] = alpha_.rate_alpha_m(U[i], Un[i], Udotn[i]);
      } else {
        lv.v[i] = U[i];  // pressure at t_{n+1}
      }
    }
    CELLFSI_PETSC(PetscLogFlops(5.0 * static_cast<double>(unknowns.size())));
  };
  if (part == kAssemblyPart) step(own_unknowns_.unknowns);
  step(g.of_elements.unknowns);
  set_step_scalars(lv);
  return lv;
}

void DivConformingFluid::scatter(const std::vector<double>& U, Vec X) const {
  if (U.size() != petsc_index_.size())
    throw std::invalid_argument("DivConformingFluid::scatter: " + std::to_string(U.size()) + " values for " +
                                std::to_string(petsc_index_.size()) + " unknowns");
  // This rank's rows only (every unknown on every rank was 0.9 ms a call at 64^3, which did not divide).
  PetscScalar* xp;
  CELLFSI_PETSC(VecGetArray(X, &xp));
  for (std::size_t k = 0; k < owned_natural_.size(); ++k) xp[k] = U[owned_natural_[k]];
  CELLFSI_PETSC(VecRestoreArray(X, &xp));
  CELLFSI_PETSC(PetscLogFlops(2.0 * owned_natural_.size()));
}

DcSolveStats DivConformingFluid::newton(std::vector<double>& U,
                                        const std::function<Levels(const std::vector<double>&)>& levels) {
  const int n = space_.n_dofs();
  matrix();  // (made at the first solve)
  DcSolveStats st;
  double f0 = -1;
  for (int it = 0; it <= opt_.newton_max_it; ++it) {
    const Levels lv = levels(U);
    const bool last = it == opt_.newton_max_it;
    assemble(lv, F_, last ? nullptr : J_);
    PetscScalar* f;
    CELLFSI_PETSC(VecGetArray(F_, &f));
    for (PetscInt r : owned_fixed_) f[r - row_begin_] = 0.0;
    CELLFSI_PETSC(VecRestoreArray(F_, &f));
    PetscReal fn = 0;
    CELLFSI_PETSC(VecNorm(F_, NORM_2, &fn));
    st.residual_norm = fn;
    if (f0 < 0) f0 = fn;
    if (fn == 0.0 || (it > 0 && fn <= opt_.newton_rtol * f0)) {
      st.converged = true;
      break;
    }
    if (last) break;
    CELLFSI_PETSC(MatZeroRows(J_, static_cast<PetscInt>(owned_fixed_.size()), owned_fixed_.data(), 1.0,
                              nullptr, nullptr));
    CELLFSI_PETSC(VecScale(F_, -1.0));
    CELLFSI_PETSC(KSPSetOperators(ksp_, J_, J_));
    CELLFSI_PETSC(KSPSolve(ksp_, F_, x_));
    KSPConvergedReason reason;
    CELLFSI_PETSC(KSPGetConvergedReason(ksp_, &reason));
    if (reason < 0) break;
    CELLFSI_PETSC(VecScatterBegin(to_all_, x_, x_all_, INSERT_VALUES, SCATTER_FORWARD));
    CELLFSI_PETSC(VecScatterEnd(to_all_, x_, x_all_, INSERT_VALUES, SCATTER_FORWARD));
    const PetscScalar* xp;
    CELLFSI_PETSC(VecGetArrayRead(x_all_, &xp));
    double dmax = 0, umax = 0;
    for (int i = 0; i < n; ++i) {
      const double dx = xp[petsc_index_[i]];
      U[i] += dx;
      dmax = std::max(dmax, std::abs(dx));
      umax = std::max(umax, std::abs(U[i]));
    }
    CELLFSI_PETSC(VecRestoreArrayRead(x_all_, &xp));
    st.newton_iterations = it + 1;
    if (dmax <= opt_.newton_stol * umax) {  // the update is round-off: U is the solution
      st.converged = true;
      break;
    }
  }
  return st;
}

void DivConformingFluid::shift_pressure_to_zero_mean(std::vector<double>& U) const {
  const int off = space_.offset(space_.dim());
  double area = 0, integral = 0;
  for (size_t a = 0; a < pressure_mass_.size(); ++a) {
    area += pressure_mass_[a];
    integral += pressure_mass_[a] * U[off + a];
  }
  const double mean = integral / area;  // partition of unity: sum_A q_A = 1
  for (size_t a = 0; a < pressure_mass_.size(); ++a) U[off + a] -= mean;
}

void DivConformingFluid::set_state(const std::vector<double>& u) {
  if (static_cast<int>(u.size()) != space_.n_dofs())
    throw std::invalid_argument(
        "DivConformingFluid::set_state: u must have n_dofs() = " + std::to_string(space_.n_dofs()) +
        " entries, got " + std::to_string(u.size()));
  U_ = u;
  std::fill(Udot_.begin(), Udot_.end(), 0.0);
}

std::vector<double> DivConformingFluid::project_saddle_point(const std::function<Vec3(const Vec3&)>& f) {
  const int D = space_.dim();
  std::vector<double> X(space_.n_dofs(), 0.0);
  // (v, w) - (p, div w) - (f, w) + (q, div v): the interior kernel with a = v, nu = 0, no convection, g = f.
  auto levels = [&](const std::vector<double>& U) {
    Levels lv;
    lv.v = U;
    lv.a = U;
    lv.dv_dU = 1;  // with nu = 0 and no convection v enters only through div v; a carries the mass term
    lv.da_dU = 1;
    lv.nu = 0;
    lv.convection = 0;
    lv.nitsche = false;
    lv.viscosity_field = false;
    lv.g = f;
    return lv;
  };
  const bool had_matrix = matrix_made();
  DcSolveStats st;
  try {
    st = newton(X, levels);
  } catch (...) {
    if (!had_matrix) release_matrix();
    throw;
  }
  if (!had_matrix) release_matrix();  // (a coupled run with the bulk stencil needs it no more)
  if (!st.converged)
    throw std::runtime_error("DivConformingFluid::project_initial_state: the projection's solve failed");
  for (int i = space_.offset(D); i < space_.n_dofs(); ++i) X[i] = 0.0;
  return X;
}

void DivConformingFluid::project_initial_state(const std::function<Vec3(const Vec3&)>& v0,
                                               const std::function<Vec3(const Vec3&)>& vdot0) {
  // A field uniform along the periodic directions with no component along the others (rest, a shear or
  // channel profile) has project_columnar's projection: no saddle-point solve (no factorisation).
  std::vector<double> X;
  U_ = project_columnar(v0, X) ? X : project_saddle_point(v0);
  Udot_ = project_columnar(vdot0, X) ? X : project_saddle_point(vdot0);
  time_ = 0;
  steps_ = 0;
  div_history_.clear();
}

bool DivConformingFluid::project_columnar(const std::function<Vec3(const Vec3&)>& f,
                                          std::vector<double>& X) const {
  // Is f uniform along the periodic directions, with no component along the others? Checked at the Gauss
  // points of every element against f at the same point moved to the periodic directions' lower end; the
  // tolerance is round-off of f's largest value.
  const int D = space_.dim(), ng = n_gauss();
  ElementBasis eb;
  double largest = 0, deviation = 0;
  if (space_.is_mapped()) {  // only rest: a profile along a curved channel is not one column's
    for (int e = 0; e < space_.n_elements() && largest == 0; ++e) {
      const Index3 ei = space_.element_multi_index(e);
      space_.evaluate(ei, space_.element_rule(ei, ng), eb);
      for (int q = 0; q < eb.n_points; ++q) largest = std::max(largest, f(eb.x[q]).norm());
    }
    if (largest > 0) return false;
    X.assign(space_.n_dofs(), 0.0);
    return true;
  }
  for (int e = 0; e < space_.n_elements(); ++e) {
    const Index3 ei = space_.element_multi_index(e);
    space_.evaluate(ei, space_.element_rule(ei, ng), eb);
    for (int q = 0; q < eb.n_points; ++q) {
      Vec3 x0 = eb.x[q];
      for (int d = 0; d < D; ++d)
        if (space_.periodic(d)) x0[d] = space_.lo(d);
      const Vec3 v = f(eb.x[q]), v0 = f(x0);
      for (int c = 0; c < D; ++c) {
        largest = std::max(largest, std::abs(v[c]));
        deviation = std::max(deviation, std::abs(v[c] - v0[c]));
        if (!space_.periodic(c)) deviation = std::max(deviation, std::abs(v[c]));
      }
    }
  }
  if (!(deviation <= 1e-14 * largest)) return false;
  X.assign(space_.n_dofs(), 0.0);
  if (largest == 0) return true;
  // Per velocity component c along a periodic direction: the coefficients are constant along the periodic
  // directions (the periodic B-splines sum to 1 there), so the field is sum_I c_I N_I over the non-periodic
  // directions' functions I; the c_I are the L2 projection over one column of elements (those with periodic
  // element index 0), with the basis summed over the periodic indices.
  for (int c = 0; c < D; ++c) {
    if (!space_.periodic(c)) continue;
    auto column_index = [&](int global) {  // I: the multi-index's non-periodic part, linearised
      const Index3 i = space_.multi_index(c, global);
      int I = 0, stride = 1;
      for (int d = 0; d < D; ++d) {
        if (space_.periodic(d)) continue;
        I += i[d] * stride;
        stride *= space_.n_basis(c, d);
      }
      return I;
    };
    int n_col = 1;
    for (int d = 0; d < D; ++d)
      if (!space_.periodic(d)) n_col *= space_.n_basis(c, d);
    std::vector<Eigen::Triplet<double>> entries;
    Eigen::VectorXd load = Eigen::VectorXd::Zero(n_col);
    std::vector<int> I;
    std::vector<double> N;
    for (int e = 0; e < space_.n_elements(); ++e) {
      const Index3 ei = space_.element_multi_index(e);
      bool in_column = true;
      for (int d = 0; d < D; ++d) in_column = in_column && (!space_.periodic(d) || ei[d] == 0);
      if (!in_column) continue;
      space_.evaluate(ei, space_.element_rule(ei, ng), eb);
      const ComponentBasis& cb = eb.comp[c];
      for (int q = 0; q < eb.n_points; ++q) {
        I.clear();
        N.clear();
        for (int a = 0; a < cb.n; ++a) {  // sum the functions of one I
          const int J = column_index(cb.index[a]);
          const auto it = std::find(I.begin(), I.end(), J);
          if (it == I.end()) {
            I.push_back(J);
            N.push_back(cb.value[q * cb.n + a]);
          } else {
            N[it - I.begin()] += cb.value[q * cb.n + a];
          }
        }
        const double fc = f(eb.x[q])[c];
        for (size_t a = 0; a < I.size(); ++a) {
          load[I[a]] += eb.weight[q] * N[a] * fc;
          for (size_t b = 0; b < I.size(); ++b) entries.emplace_back(I[a], I[b], eb.weight[q] * N[a] * N[b]);
        }
      }
    }
    const Eigen::VectorXd coeffs =
        solve_mass_matrix(n_col, entries, load, "DivConformingFluid::project_initial_state: a column's");
    for (int g = space_.offset(c); g < space_.offset(c) + space_.n_basis(c); ++g)
      X[g] = coeffs[column_index(g)];
  }
  return true;
}

DivConformingFluid::Levels DivConformingFluid::steady_levels(const std::vector<double>& U) const {
  Levels lv;
  lv.v = U;
  lv.a.assign(U.size(), 0.0);
  lv.dv_dU = 1;
  lv.da_dU = 0;
  lv.nu = opt_.viscosity / opt_.density;
  lv.convection = opt_.stokes ? 0.0 : 1.0;
  lv.t = time_;
  lv.g = body_force_per_mass(time_);
  return lv;
}

DivConformingFluid::Levels DivConformingFluid::step_levels(const std::vector<double>& U,
                                                           const std::vector<double>& Un,
                                                           const std::vector<double>& Udotn) const {
  const int n = space_.n_dofs(), nv = space_.n_velocity();
  Levels lv;
  lv.v.resize(n);
  lv.a.assign(n, 0.0);
  for (int i = 0; i < nv; ++i) {
    lv.v[i] = alpha_.value_alpha_f(U[i], Un[i]);
    lv.a[i] = alpha_.rate_alpha_m(U[i], Un[i], Udotn[i]);
  }
  for (int i = nv; i < n; ++i) lv.v[i] = U[i];  // pressure at t_{n+1}
  set_step_scalars(lv);
  // (-log_view's counts: every unknown on every rank, 5 operations each; part_levels takes a rank's share)
  CELLFSI_PETSC(PetscLogFlops(5.0 * n));
  return lv;
}

void DivConformingFluid::set_step_scalars(Levels& lv) const {
  lv.dv_dU = alpha_.alpha_f;
  lv.da_dU = alpha_.rate_alpha_m_scale();
  lv.nu = opt_.viscosity / opt_.density;
  lv.convection = opt_.stokes ? 0.0 : 1.0;
  lv.t = time_ + alpha_.alpha_f * opt_.dt;
  lv.g = body_force_per_mass(lv.t);
}

std::function<Vec3(const Vec3&)> DivConformingFluid::body_force_per_mass(double t) const {
  return [this, t](const Vec3& x) {
    Vec3 f = opt_.body_force;
    if (opt_.body_force_field) f += opt_.body_force_field(x, t);
    return Vec3(f / opt_.density);
  };
}

DcSolveStats DivConformingFluid::solve_steady() {
  bool any_wall = false;
  for (int d = 0; d < space_.dim(); ++d) any_wall = any_wall || !space_.periodic(d);
  if (!any_wall)
    throw std::invalid_argument(
        "DivConformingFluid::solve_steady: on a box periodic in every direction the steady problem is "
        "singular "
        "(any constant velocity can be added); give a direction walls, or advance in time with step()");
  const DcSolveStats st = newton(U_, [this](const std::vector<double>& U) { return steady_levels(U); });
  shift_pressure_to_zero_mean(U_);
  return st;
}

DcSolveStats DivConformingFluid::step() {
  const int nv = space_.n_velocity();
  const std::vector<double> Un = U_, Udotn = Udot_;
  std::vector<double> X = U_;  // predictor: the same state
  const DcSolveStats st = newton(X, [&](const std::vector<double>& U) { return step_levels(U, Un, Udotn); });
  if (!st.converged) return st;
  for (int i = 0; i < nv; ++i) Udot_[i] = alpha_.rate(X[i], Un[i], Udotn[i]);
  U_ = X;
  shift_pressure_to_zero_mean(U_);
  ++steps_;
  time_ = steps_ * opt_.dt;
  div_history_.push_back(divergence_ratio());
  return st;
}

Mat DivConformingFluid::jacobian(bool time_step, bool pin_pressure) {
  const Levels lv = time_step ? step_levels(U_, U_, Udot_) : steady_levels(U_);
  Mat J = matrix();
  assemble(lv, F_, J);
  zero_fixed_rows(J, pin_pressure, 1.0);
  return J;
}

DivConformingFluid::Errors DivConformingFluid::errors(
    const std::function<Vec3(const Vec3&)>& v, const std::function<geometry::Mat3(const Vec3&)>& grad_v,
    const std::function<double(const Vec3&)>& p) const {
  const int D = space_.dim();
  const int ng = space_.degree() + 4;
  // Means of the two pressures first.
  double means[3] = {0, 0, 0};  // volume, int p_h, int p
  for_owned_elements(ng, [&](const ElementBasis& eb) {
    for (int q = 0; q < eb.n_points; ++q) {
      const auto pv = DivConformingSpace::interpolate(eb, q, D, U_.data());
      means[0] += eb.weight[q];
      means[1] += eb.weight[q] * pv.p;
      means[2] += eb.weight[q] * p(eb.x[q]);
    }
  });
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, means, 3, MPI_DOUBLE, MPI_SUM, comm_));
  const double mean_h = means[1] / means[0], mean_ex = means[2] / means[0];
  double sums[6] = {0, 0, 0, 0, 0, 0};  // squares: v L2, v H1, p L2 errors, then the exact norms
  for_owned_elements(ng, [&](const ElementBasis& eb) {
    for (int q = 0; q < eb.n_points; ++q) {
      const auto pv = DivConformingSpace::interpolate(eb, q, D, U_.data());
      const Vec3 ve = v(eb.x[q]);
      const geometry::Mat3 ge = grad_v(eb.x[q]);
      const double pe = p(eb.x[q]) - mean_ex, w = eb.weight[q];
      for (int i = 0; i < D; ++i) {
        sums[0] += w * std::pow(pv.v[i] - ve[i], 2);
        sums[3] += w * ve[i] * ve[i];
        for (int j = 0; j < D; ++j) {
          sums[1] += w * std::pow(pv.grad[i][j] - ge(i, j), 2);
          sums[4] += w * ge(i, j) * ge(i, j);
        }
      }
      sums[2] += w * std::pow(pv.p - mean_h - pe, 2);
      sums[5] += w * pe * pe;
    }
  });
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, sums, 6, MPI_DOUBLE, MPI_SUM, comm_));
  Errors er;
  er.v_l2 = std::sqrt(sums[0]);
  er.v_h1 = std::sqrt(sums[1]);
  er.p_l2 = std::sqrt(sums[2]);
  er.v_l2_norm = std::sqrt(sums[3]);
  er.v_h1_norm = std::sqrt(sums[4]);
  er.p_l2_norm = std::sqrt(sums[5]);
  return er;
}

double DivConformingFluid::divergence_ratio() const {
  // By sum factorisation over blocks of elements of one basis class, as interior_residual_batched (a
  // point at a time through the whole basis it took 1 s of every step of the 3D compound capsule at 64^3 on
  // two ranks, every rank its own elements).
  const int D = space_.dim();
  double m[2] = {0, 0};  // max |div v_h|, max |grad v_h|
  if (space_.is_mapped()) {  // point by point through the map (the physical gradient)
    for (int e = elem_begin_; e < elem_end_; ++e) {
      const ElementBasis& eb = element_basis(e);
      for (int q = 0; q < eb.n_points; ++q) {
        const auto pv = DivConformingSpace::interpolate(eb, q, D, U_.data());
        double div = 0, g2 = 0;
        for (int i = 0; i < D; ++i) {
          div += pv.grad[i][i];
          for (int j = 0; j < D; ++j) g2 += pv.grad[i][j] * pv.grad[i][j];
        }
        m[0] = std::max(m[0], std::abs(div));
        m[1] = std::max(m[1], g2);
      }
    }
    m[1] = std::sqrt(m[1]);
    CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, m, 2, MPI_DOUBLE, MPI_MAX, comm_));
    return m[1] > 0 ? m[0] / m[1] : 0.0;
  }
  constexpr int kBlock = 128;
  std::vector<double> u, grad[3][3], scratch;
  for (const std::vector<int>& members : elements_by_class()) {
    if (members.empty()) continue;
    const Index3 ei = space_.element_multi_index(members.front());
    const TensorRule rule = space_.element_rule(ei, n_gauss());
    ComponentFactors fac[3];
    int off[4] = {0, 0, 0, 0};
    for (int c = 0; c < D; ++c) {
      fac[c] = component_factors(space_, c, ei, rule);
      off[c + 1] = off[c] + fac[c].n_functions();
    }
    const int nq = fac[0].n_points();
    for (size_t first = 0; first < members.size(); first += kBlock) {
      const int mb = static_cast<int>(std::min<size_t>(kBlock, members.size() - first));
      const size_t mq = static_cast<size_t>(nq) * mb;
      for (int c = 0; c < D; ++c) {
        gather_block(members.data() + first, mb, off[c], fac[c].n_functions(), U_.data(), 0, u);
        for (auto& g : grad[c]) g.resize(mq);
        const std::array<double*, 3> gp{grad[c][0].data(), grad[c][1].data(), grad[c][2].data()};
        sum_factorized_values(fac[c], mb, u.data(), nullptr, &gp, scratch);  // (the gradient alone)
      }
      for (size_t k = 0; k < mq; ++k) {
        double div = 0, g2 = 0;
        for (int i = 0; i < D; ++i) {
          div += grad[i][i][k];
          for (int j = 0; j < D; ++j) g2 += grad[i][j][k] * grad[i][j][k];
        }
        m[0] = std::max(m[0], std::abs(div));
        m[1] = std::max(m[1], g2);
      }
    }
  }
  m[1] = std::sqrt(m[1]);
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, m, 2, MPI_DOUBLE, MPI_MAX, comm_));
  return m[1] > 0 ? m[0] / m[1] : 0.0;
}

double DivConformingFluid::max_velocity() const {
  const int D = space_.dim();
  double vmax = 0;
  for_owned_elements(n_gauss(), [&](const ElementBasis& eb) {
    for (int q = 0; q < eb.n_points; ++q) {
      const auto pv = DivConformingSpace::interpolate(eb, q, D, U_.data());
      double v2 = 0;
      for (int i = 0; i < D; ++i) v2 += pv.v[i] * pv.v[i];
      vmax = std::max(vmax, std::sqrt(v2));
    }
  });
  CELLFSI_PETSC(MPI_Allreduce(MPI_IN_PLACE, &vmax, 1, MPI_DOUBLE, MPI_MAX, comm_));
  return vmax;
}

void DivConformingFluid::restore(const std::vector<double>& u, const std::vector<double>& udot, int steps) {
  if (steps < 0) throw std::invalid_argument("DivConformingFluid::restore: steps must be >= 0");
  set_state(u);
  if (udot.size() != u.size())
    throw std::invalid_argument("DivConformingFluid::restore: udot must have as many entries as u");
  Udot_ = udot;
  steps_ = steps;
  time_ = steps_ * opt_.dt;
}

std::vector<DivConformingFluid::Sample> DivConformingFluid::sample(const std::vector<Vec3>& points) const {
  const int D = space_.dim();
  std::vector<Sample> out(points.size());
  ElementBasis eb;
  // (made once: its set-up visits every element)
  if (space_.is_mapped() && !inverter_)
    inverter_ = std::make_unique<geometry::PointInverter>(*space_.patch());
  const geometry::PointInverter* inverter = inverter_.get();
  TensorRule rule;
  geometry::InversionResult previous;
  for (size_t i = 0; i < points.size(); ++i) {
    if (inverter) {  // (warm from the previous point: output grids and profiles come in order)
      const geometry::InversionResult loc = i > 0 && previous.inside
                                                ? inverter->invert(points[i], previous.element, previous.xi)
                                                : inverter->invert(points[i]);
      const geometry::InversionResult found = loc.inside ? loc : inverter->invert(points[i]);
      if (!found.inside)
        throw std::invalid_argument("DivConformingFluid::sample: the point (" + std::to_string(points[i][0]) +
                                    ", " + std::to_string(points[i][1]) + ", " +
                                    std::to_string(points[i][2]) + ") is outside the domain (by " +
                                    std::to_string(found.distance) + " cm)");
      previous = found;
      for (int d = 0; d < 3; ++d) {
        rule.points[d].assign(1, d < D ? space_.from_patch_parameters(found.xi)[d] : 0.0);
        rule.weights[d].assign(1, 1.0);
      }
      space_.evaluate(found.element, rule, eb);
    } else {
      space_.evaluate(space_.find_element(points[i]), space_.point_rule(points[i]), eb);
    }
    const auto pv = DivConformingSpace::interpolate(eb, 0, D, U_.data());
    for (int a = 0; a < D; ++a) {
      out[i].v[a] = pv.v[a];
      for (int b = 0; b < D; ++b) out[i].grad_v(a, b) = pv.grad[a][b];
    }
    out[i].p = pv.p;
  }
  return out;
}

void DivConformingFluid::write_vtk(const std::string& path, int samples_per_element) const {
  if (samples_per_element < 1)
    throw std::invalid_argument("DivConformingFluid::write_vtk: samples_per_element must be >= 1, got " +
                                std::to_string(samples_per_element));
  int rank = 0;
  CELLFSI_PETSC(MPI_Comm_rank(comm_, &rank));
  const int D = space_.dim(), s = samples_per_element;
  int n[3] = {1, 1, 1};
  for (int d = 0; d < D; ++d) n[d] = space_.n_elements(d) * s + 1;
  // Rank 0 writes; the others wait for it so that the file exists when the call returns everywhere, and learn
  // whether it failed.
  int failed = 0;
  std::string message;
  if (rank == 0) {
    try {
      std::vector<Vec3> pts;
      std::vector<Sample> smp;
      pts.reserve(static_cast<size_t>(n[0]) * n[1] * n[2]);
      ElementBasis eb;
      TensorRule rule;
      for (int m2 = 0; m2 < n[2]; ++m2)
        for (int m1 = 0; m1 < n[1]; ++m1)
          for (int m0 = 0; m0 < n[0]; ++m0) {
            const int m[3] = {m0, m1, m2};
            Vec3 x = Vec3::Zero();
            for (int d = 0; d < D; ++d)
              x[d] = space_.lo(d) + (space_.hi(d) - space_.lo(d)) * m[d] / (n[d] - 1);
            if (!space_.is_mapped()) {
              pts.push_back(x);
              continue;
            }
            // A mapped space: x is the parametric point; its element's (the last along a direction for the
            // end sample), evaluated there and mapped.
            Index3 e{0, 0, 0};
            for (int d = 0; d < D; ++d) e[d] = std::min(m[d] / s, space_.n_elements(d) - 1);
            for (int d = 0; d < 3; ++d) {
              rule.points[d].assign(1, x[d]);
              rule.weights[d].assign(1, 1.0);
            }
            space_.evaluate(e, rule, eb);
            const auto pv = DivConformingSpace::interpolate(eb, 0, D, U_.data());
            Sample sm;
            for (int a = 0; a < D; ++a) {
              sm.v[a] = pv.v[a];
              for (int b = 0; b < D; ++b) sm.grad_v(a, b) = pv.grad[a][b];
            }
            sm.p = pv.p;
            smp.push_back(sm);
            pts.push_back(eb.x[0]);
          }
      // A periodic direction's last sample, at the period's end, is wrapped to its start: the same value.
      if (!space_.is_mapped()) smp = sample(pts);
      vtkNew<vtkStructuredGrid> grid;
      grid->SetDimensions(n[0], n[1], n[2]);
      vtkNew<vtkPoints> points;
      points->SetDataTypeToDouble();
      vtkNew<vtkDoubleArray> vel, pre, dvg;
      vel->SetName("velocity");
      vel->SetNumberOfComponents(3);
      pre->SetName("pressure");
      dvg->SetName("divergence");
      for (size_t i = 0; i < pts.size(); ++i) {
        points->InsertNextPoint(pts[i][0], pts[i][1], pts[i][2]);
        vel->InsertNextTuple3(smp[i].v[0], smp[i].v[1], smp[i].v[2]);
        pre->InsertNextValue(smp[i].p);
        dvg->InsertNextValue(smp[i].grad_v.trace());
      }
      grid->SetPoints(points);
      grid->GetPointData()->AddArray(vel);
      grid->GetPointData()->AddArray(pre);
      grid->GetPointData()->AddArray(dvg);
      vtkNew<vtkXMLStructuredGridWriter> writer;
      writer->SetInputData(grid);
      geometry::write_vtk_atomically(writer, path);
    } catch (const std::exception& e) {
      failed = 1;
      message = e.what();
    }
  }
  CELLFSI_PETSC(MPI_Bcast(&failed, 1, MPI_INT, 0, comm_));
  if (failed)
    throw std::runtime_error("DivConformingFluid::write_vtk: " +
                             (rank == 0 ? message : std::string("rank 0 failed")));
}

void DivConformingFluid::set_viscosity(const std::vector<double>& mu) {
  if (static_cast<int>(mu.size()) != space_.n_pressure())
    throw std::invalid_argument("DivConformingFluid::set_viscosity: mu must have n_pressure() = " +
                                std::to_string(space_.n_pressure()) + " entries, got " +
                                std::to_string(mu.size()));
  for (double m : mu)
    if (!(m > 0))
      throw std::invalid_argument(
          "DivConformingFluid::set_viscosity: every viscosity must be > 0 g/(cm s), got " +
          std::to_string(m));
  nu_field_.resize(mu.size());
  for (size_t a = 0; a < mu.size(); ++a) nu_field_[a] = mu[a] / opt_.density;
}

void DivConformingFluid::project_viscosity(const std::function<double(const Vec3&)>& mu) {
  // The pressure-space mass matrix and load over every element on every rank (the field, like the state, is
  // on every rank), solved by sparse Cholesky.
  const int D = space_.dim(), np = space_.n_pressure(), off = space_.offset(D);
  std::vector<Eigen::Triplet<double>> entries;
  Eigen::VectorXd load = Eigen::VectorXd::Zero(np);
  ElementBasis eb;
  for (int e = 0; e < space_.n_elements(); ++e) {
    const Index3 ei = space_.element_multi_index(e);
    space_.evaluate(ei, space_.element_rule(ei, n_gauss()), eb);
    const ComponentBasis& cb = eb.comp[D];
    for (int q = 0; q < eb.n_points; ++q) {
      const double m = mu(eb.x[q]);
      for (int a = 0; a < cb.n; ++a) {
        const double wa = eb.weight[q] * cb.value[q * cb.n + a];
        load[cb.index[a] - off] += wa * m;
        for (int b = 0; b < cb.n; ++b)
          entries.emplace_back(cb.index[a] - off, cb.index[b] - off, wa * cb.value[q * cb.n + b]);
      }
    }
  }
  const Eigen::VectorXd coeffs =
      solve_mass_matrix(np, entries, load, "DivConformingFluid::project_viscosity: the pressure space's");
  nu_field_.resize(np);
  for (int a = 0; a < np; ++a) nu_field_[a] = coeffs[a] / opt_.density;
}

}  // namespace cellfsi::fluid::dc
