#include "fluid/fluid_output.hpp"

#include <cstdio>
#include <filesystem>
#include <stdexcept>

#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkStructuredGrid.h>
#include <vtkXMLStructuredGridWriter.h>

#include "common/petsc_error.hpp"
#include "geometry/quadrature.hpp"

namespace cellfsi::fluid {

using geometry::BasisValues;
using geometry::MapValues;
using geometry::Mat3;
using geometry::Param;
using geometry::Vec3;

namespace {

/// Velocity, its gradient and the kinematic pressure from natural-ordered nodal values (rank 0 data).
struct Local {
  Vec3 x = Vec3::Zero(), v = Vec3::Zero();
  Mat3 grad = Mat3::Zero();
  double p = 0, s = 0;
};
Local evaluate(const geometry::Patch& patch, const std::vector<double>& U, const std::vector<double>& S,
               int dof, const Param& xi, BasisValues& bv, MapValues& mv) {
  const int D = patch.param_dim();
  patch.basis(xi, 1, bv);
  patch.map(bv, mv);
  Mat3 Ji = Mat3::Identity();
  Ji.topLeftCorner(D, D) = mv.dx.topLeftCorner(D, D).inverse();
  Local r;
  r.x = mv.x;
  for (int k = 0; k < bv.n; ++k) {
    const int node = bv.index[k];
    double g[3] = {0, 0, 0};
    for (int j = 0; j < D; ++j)
      for (int a = 0; a < D; ++a) g[j] += bv.d1[3 * k + a] * Ji(a, j);
    for (int c = 0; c < D; ++c) {
      const double val = U[node * dof + c];
      r.v[c] += bv.value[k] * val;
      for (int j = 0; j < D; ++j) r.grad(c, j) += g[j] * val;
    }
    r.p += bv.value[k] * U[node * dof + D];
    if (!S.empty()) r.s += bv.value[k] * S[node];
  }
  return r;
}

}  // namespace

FluidSeriesWriter::FluidSeriesWriter(std::string dir, int samples_per_element)
    : dir_(std::move(dir)), samples_(samples_per_element) {
  if (samples_ < 1) throw std::invalid_argument("fluid output: samples per element must be >= 1");
}

void FluidSeriesWriter::write(const FluidSolver& fluid) {
  // Both gathers are collective: every rank takes part before the others return.
  const std::vector<double> U = fluid.gather_to_zero(fluid.solution());
  const std::vector<double> S = fluid.scaling_on_zero();
  PetscMPIInt rank = 0;
  MPI_Comm_rank(fluid.comm(), &rank);
  if (rank != 0) return;
  const geometry::Patch& patch = fluid.patch();
  const int D = fluid.dim(), dof = D + 1;
  const double rho = fluid.options().density;
  std::vector<double> u[3] = {{0.0}, {0.0}, {0.0}};
  for (int d = 0; d < D; ++d) u[d] = geometry::sample_values(patch.knots(d), samples_);
  const int n0 = u[0].size(), n1 = u[1].size(), n2 = u[2].size();
  const vtkIdType n = static_cast<vtkIdType>(n0) * n1 * n2;

  vtkNew<vtkStructuredGrid> grid;
  grid->SetDimensions(n0, n1, n2);
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(n);
  auto array = [&](const char* name, int comps) {
    vtkNew<vtkDoubleArray> a;
    a->SetName(name);
    a->SetNumberOfComponents(comps);
    a->SetNumberOfTuples(n);
    grid->GetPointData()->AddArray(a);
    return vtkDoubleArray::SafeDownCast(grid->GetPointData()->GetArray(name));
  };
  vtkDoubleArray* vel = array("velocity", 3);
  vtkDoubleArray* pre = array("pressure", 1);
  vtkDoubleArray* vor = array("vorticity", D == 2 ? 1 : 3);
  vtkDoubleArray* sh = array("s_h", 1);
  vtkDoubleArray* dis = undisturbed_ ? array("velocity_disturbance", 3) : nullptr;
  BasisValues bv;
  MapValues mv;
  vtkIdType id = 0;
  for (int k = 0; k < n2; ++k)
    for (int j = 0; j < n1; ++j)
      for (int i = 0; i < n0; ++i, ++id) {
        const Local l = evaluate(patch, U, S, dof, {u[0][i], u[1][j], u[2][k]}, bv, mv);
        points->SetPoint(id, l.x.data());
        vel->SetTuple3(id, l.v[0], l.v[1], l.v[2]);
        pre->SetValue(id, rho * l.p);
        sh->SetValue(id, l.s);
        if (dis) {
          const geometry::Vec3 d = l.v - undisturbed_(l.x);
          dis->SetTuple3(id, d[0], d[1], d[2]);
        }
        if (D == 2) {
          vor->SetValue(id, l.grad(1, 0) - l.grad(0, 1));
        } else {
          vor->SetTuple3(id, l.grad(2, 1) - l.grad(1, 2), l.grad(0, 2) - l.grad(2, 0),
                         l.grad(1, 0) - l.grad(0, 1));
        }
      }
  grid->SetPoints(points);
  char name[64];
  std::snprintf(name, sizeof name, "fluid_%06d.vts", fluid.steps_taken());
  const std::string path = (std::filesystem::path(dir_) / name).string();
  // Written under a temporary name and renamed: a run killed mid-write leaves no truncated file.
  const std::string tmp = path + ".tmp";
  vtkNew<vtkXMLStructuredGridWriter> writer;
  writer->SetFileName(tmp.c_str());
  writer->SetInputData(grid);
  if (writer->Write() != 1 || writer->GetErrorCode() != 0)
    throw std::runtime_error("cannot write VTK file '" + tmp + "'");
  if (std::rename(tmp.c_str(), path.c_str()) != 0) throw std::runtime_error("cannot rename '" + tmp + "'");
  entries_.push_back({name, fluid.time(), 0, ""});  // time is steps * dt: no accumulated round-off
  geometry::write_pvd((std::filesystem::path(dir_) / "fluid.pvd").string(), entries_);
}

SectionData section(const FluidSolver& fluid, double u0, int n_profile) {
  const std::vector<double> U = fluid.gather_to_zero(fluid.solution());
  SectionData out;
  PetscMPIInt rank = 0;
  MPI_Comm_rank(fluid.comm(), &rank);
  const geometry::Patch& patch = fluid.patch();
  const int D = fluid.dim(), dof = D + 1;
  double buf[2] = {0, 0};
  std::vector<double> prof(6 * n_profile, 0.0);
  if (rank == 0) {
    BasisValues bv;
    MapValues mv;
    std::vector<geometry::QuadraturePoint> qp;
    const std::vector<double> none;
    // Integrate v . (dx/dxi_1 x dx/dxi_2) (3D) or v . (dy/deta, -dx/deta) (2D) over the section's elements.
    const geometry::GaussRule& g = geometry::gauss_legendre(patch.degree(1) + 3);
    const geometry::KnotVector& k1 = patch.knots(1);
    const int n2 = D == 3 ? patch.knots(2).n_elements() : 1;
    const geometry::GaussRule& g2 = geometry::gauss_legendre(D == 3 ? patch.degree(2) + 3 : 1);
    for (int e1 = 0; e1 < k1.n_elements(); ++e1)
      for (int e2 = 0; e2 < n2; ++e2)
        for (size_t q1 = 0; q1 < g.points.size(); ++q1)
          for (size_t q2 = 0; q2 < (D == 3 ? g2.points.size() : 1); ++q2) {
            const double a1 = k1.element_begin(e1), b1 = k1.element_end(e1);
            Param xi{u0, a1 + 0.5 * (b1 - a1) * (g.points[q1] + 1), 0};
            double w = 0.5 * (b1 - a1) * g.weights[q1];
            if (D == 3) {
              const geometry::KnotVector& k2 = patch.knots(2);
              const double a2 = k2.element_begin(e2), b2 = k2.element_end(e2);
              xi[2] = a2 + 0.5 * (b2 - a2) * (g2.points[q2] + 1);
              w *= 0.5 * (b2 - a2) * g2.weights[q2];
            }
            const Local l = evaluate(patch, U, none, dof, xi, bv, mv);
            Vec3 nA;
            if (D == 2)
              nA = Vec3(mv.dx(1, 1), -mv.dx(0, 1), 0);
            else
              nA = mv.dx.col(1).cross(mv.dx.col(2));
            buf[0] += w * l.v.dot(nA);
            buf[1] += w * nA.norm();
          }
    for (int i = 0; i < n_profile; ++i) {
      const Param xi{u0, k1.a() + (k1.b() - k1.a()) * i / (n_profile - 1), D == 3 ? 0.5 : 0.0};
      const Local l = evaluate(patch, U, none, dof, xi, bv, mv);
      for (int c = 0; c < 3; ++c) prof[6 * i + c] = l.x[c], prof[6 * i + 3 + c] = l.v[c];
    }
  }
  CELLFSI_PETSC(MPI_Bcast(buf, 2, MPI_DOUBLE, 0, fluid.comm()));
  CELLFSI_PETSC(MPI_Bcast(prof.data(), static_cast<int>(prof.size()), MPI_DOUBLE, 0, fluid.comm()));
  out.flow_rate = std::abs(buf[0]);
  out.area = buf[1];
  for (int i = 0; i < n_profile; ++i) {
    out.points.emplace_back(prof[6 * i], prof[6 * i + 1], prof[6 * i + 2]);
    out.velocity.emplace_back(prof[6 * i + 3], prof[6 * i + 4], prof[6 * i + 5]);
  }
  return out;
}

}  // namespace cellfsi::fluid
