#include "fluid/fluid_output.hpp"

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkStructuredGrid.h>
#include <vtkXMLStructuredGridWriter.h>

#include "common/collective.hpp"
#include "common/file_io.hpp"
#include "common/petsc_error.hpp"
#include "fluid/fluid_solver.hpp"
#include "fluid/point_evaluation.hpp"
#include "geometry/quadrature.hpp"

namespace cellfsi::fluid {

using geometry::BasisValues;
using geometry::MapValues;
using geometry::Mat3;
using geometry::Param;
using geometry::Vec3;

namespace {

/// A VTK file written under a temporary name and renamed: a run killed mid-write leaves no truncated file.
void write_atomically(vtkStructuredGrid* grid, const std::string& path) {
  vtkNew<vtkXMLStructuredGridWriter> writer;
  writer->SetInputData(grid);
  geometry::write_vtk_atomically(writer, path);
}

/// The .pvts index of a series step: the whole sample grid and each rank's piece (extent, file).
void write_pvts(const std::string& path, const int whole[6], const std::vector<std::array<int, 6>>& extents,
                const std::vector<std::string>& files,
                const std::vector<std::pair<std::string, int>>& arrays) {
  std::ostringstream os;
  auto extent = [](const int* e) {
    std::ostringstream x;
    x << e[0] << ' ' << e[1] << ' ' << e[2] << ' ' << e[3] << ' ' << e[4] << ' ' << e[5];
    return x.str();
  };
  os << "<?xml version=\"1.0\"?>\n"
     << "<VTKFile type=\"PStructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
     << "  <PStructuredGrid WholeExtent=\"" << extent(whole) << "\" GhostLevel=\"0\">\n"
     << "    <PPointData>\n";
  for (const auto& [name, comps] : arrays)
    os << "      <PDataArray type=\"Float64\" Name=\"" << name << "\" NumberOfComponents=\"" << comps
       << "\"/>\n";
  os << "    </PPointData>\n"
     << "    <PPoints>\n      <PDataArray type=\"Float64\" NumberOfComponents=\"3\"/>\n    </PPoints>\n";
  for (size_t i = 0; i < files.size(); ++i)
    os << "    <Piece Extent=\"" << extent(extents[i].data()) << "\" Source=\"" << files[i] << "\"/>\n";
  os << "  </PStructuredGrid>\n</VTKFile>\n";
  write_file_atomically(path, os.str(), false);
}

}  // namespace

FluidSeriesWriter::FluidSeriesWriter(std::string dir, int samples_per_element)
    : dir_(std::move(dir)), samples_(samples_per_element) {
  if (samples_ < 1) throw std::invalid_argument("fluid output: samples per element must be >= 1");
}

void FluidSeriesWriter::write(const ImmersedFluid& fluid) {
  char stem[64];
  std::snprintf(stem, sizeof stem, "fluid_%06d", fluid.steps_taken());
  const std::string name = fluid.write_fields(dir_, stem, samples_, undisturbed_);
  entries_.push_back({name, fluid.time(), 0, ""});  // time is steps * dt: no accumulated round-off
  on_rank_zero(fluid.comm(),
               [&] { geometry::write_pvd((std::filesystem::path(dir_) / "fluid.pvd").string(), entries_); });
}

std::string FluidSolver::write_fields(const std::string& dir_name, const std::string& stem,
                                      int samples_per_element,
                                      const std::function<Vec3(const Vec3&)>& undisturbed) const {
  // Each rank samples the elements it owns from its ghosted values: one file on one rank, and on several one
  // piece per rank (fluid_NNNNNN_pRRRR.vts) with the index fluid_NNNNNN.pvts, which ParaView reads as one
  // grid.
  const FluidSolver& fluid = *this;
  PetscMPIInt rank = 0, size = 1;
  MPI_Comm_rank(fluid.comm(), &rank);
  MPI_Comm_size(fluid.comm(), &size);
  const geometry::Patch& patch = fluid.patch();
  const int D = fluid.dim(), dof = D + 1, s = samples_per_element;
  const double rho = fluid.options().density;

  // This rank's elements (a box: a range per direction) and its piece of the sample grid.
  int lo[3] = {0, 0, 0}, hi[3] = {-1, 0, 0};  // element ranges, inclusive
  const std::vector<Index3> owned = fluid.owned_elements();
  if (!owned.empty()) {
    for (int d = 0; d < 3; ++d) lo[d] = owned.front()[d], hi[d] = owned.back()[d];
  }
  int extent[6] = {0, -1, 0, 0, 0, 0};  // sample index ranges, inclusive (ends shared with the next piece)
  if (!owned.empty())
    for (int d = 0; d < 3; ++d) {
      extent[2 * d] = d < D ? lo[d] * s : 0;
      extent[2 * d + 1] = d < D ? (hi[d] + 1) * s : 0;
    }
  const int n0 = extent[1] - extent[0] + 1, n1 = extent[3] - extent[2] + 1, n2 = extent[5] - extent[4] + 1;
  const vtkIdType n = owned.empty() ? 0 : static_cast<vtkIdType>(n0) * n1 * n2;

  Vec U_loc, S_loc, Nu_loc = nullptr;
  CELLFSI_PETSC(DMGetLocalVector(fluid.dm(), &U_loc));
  CELLFSI_PETSC(DMGlobalToLocal(fluid.dm(), fluid.solution(), INSERT_VALUES, U_loc));
  DM dm_scalar;
  CELLFSI_PETSC(VecGetDM(fluid.scaling(), &dm_scalar));
  CELLFSI_PETSC(DMGetLocalVector(dm_scalar, &S_loc));
  CELLFSI_PETSC(DMGlobalToLocal(dm_scalar, fluid.scaling(), INSERT_VALUES, S_loc));
  const PetscScalar *u, *sh, *nuh = nullptr;
  CELLFSI_PETSC(VecGetArrayRead(U_loc, &u));
  CELLFSI_PETSC(VecGetArrayRead(S_loc, &sh));
  if (fluid.viscosity_field()) {  // a viscosity field (docs/fluid.md): written as the dynamic viscosity
    CELLFSI_PETSC(DMGetLocalVector(dm_scalar, &Nu_loc));
    CELLFSI_PETSC(DMGlobalToLocal(dm_scalar, fluid.viscosity_field(), INSERT_VALUES, Nu_loc));
    CELLFSI_PETSC(VecGetArrayRead(Nu_loc, &nuh));
  }
  PetscInt gxs[3], gxm[3];
  CELLFSI_PETSC(DMDAGetGhostCorners(fluid.dm(), &gxs[0], &gxs[1], &gxs[2], &gxm[0], &gxm[1], &gxm[2]));

  vtkNew<vtkStructuredGrid> grid;
  grid->SetExtent(extent[0], extent[1], extent[2], extent[3], extent[4], extent[5]);
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->SetNumberOfPoints(n);
  std::vector<std::pair<std::string, int>> arrays;
  auto array = [&](const char* name, int comps) {
    vtkNew<vtkDoubleArray> a;
    a->SetName(name);
    a->SetNumberOfComponents(comps);
    a->SetNumberOfTuples(n);
    grid->GetPointData()->AddArray(a);
    arrays.emplace_back(name, comps);
    return vtkDoubleArray::SafeDownCast(grid->GetPointData()->GetArray(name));
  };
  vtkDoubleArray* vel = array("velocity", 3);
  vtkDoubleArray* pre = array("pressure", 1);
  vtkDoubleArray* vor = array("vorticity", D == 2 ? 1 : 3);
  vtkDoubleArray* shv = array("s_h", 1);
  vtkDoubleArray* dvg = array("divergence", 1);  // of the velocity: the discrete incompressibility error
  vtkDoubleArray* dis = undisturbed ? array("velocity_disturbance", 3) : nullptr;
  vtkDoubleArray* mu = nuh ? array("viscosity", 1) : nullptr;
  BasisValues bv;
  MapValues mv;
  PhysicalPoint pp;
  std::vector<PetscInt> nodes;
  vtkIdType id = 0;
  for (int m2 = extent[4]; m2 <= extent[5] && n > 0; ++m2)
    for (int m1 = extent[2]; m1 <= extent[3]; ++m1)
      for (int m0 = extent[0]; m0 <= extent[1]; ++m0, ++id) {
        // Sample m of direction d: point k = m - e s of element e = m / s (the piece's last element for its
        // end), at xi = begin + (end - begin) k / s, as geometry::sample_values.
        const int m[3] = {m0, m1, m2};
        Index3 e{0, 0, 0};
        Param xi{0, 0, 0};
        for (int d = 0; d < D; ++d) {
          e[d] = std::min(m[d] / s, hi[d]);
          const geometry::KnotVector& kv = patch.knots(d);
          const double a = kv.element_begin(e[d]), b = kv.element_end(e[d]);
          const int k = m[d] - e[d] * s;
          xi[d] = k == s ? b : a + (b - a) * k / s;
        }
        physical_point(patch, e, xi, 1, bv, mv, pp);
        element_nodes(patch, pp, gxs, gxm, nodes);
        const PointValues l = interpolate(pp, D, [&](int k, int c) { return u[nodes[k] * dof + c]; });
        const double s_h = interpolate(pp, 0, [&](int k, int) { return sh[nodes[k]]; }).scalar;
        points->SetPoint(id, l.x.data());
        vel->SetTuple3(id, l.v[0], l.v[1], l.v[2]);
        pre->SetValue(id, rho * l.scalar);
        shv->SetValue(id, s_h);
        dvg->SetValue(id, l.grad_v.trace());
        if (mu) mu->SetValue(id, rho * interpolate(pp, 0, [&](int k, int) { return nuh[nodes[k]]; }).scalar);
        if (dis) {
          const geometry::Vec3 dv = l.v - undisturbed(l.x);
          dis->SetTuple3(id, dv[0], dv[1], dv[2]);
        }
        if (D == 2) {
          vor->SetValue(id, l.grad_v(1, 0) - l.grad_v(0, 1));
        } else {
          vor->SetTuple3(id, l.grad_v(2, 1) - l.grad_v(1, 2), l.grad_v(0, 2) - l.grad_v(2, 0),
                         l.grad_v(1, 0) - l.grad_v(0, 1));
        }
      }
  grid->SetPoints(points);
  CELLFSI_PETSC(VecRestoreArrayRead(U_loc, &u));
  CELLFSI_PETSC(VecRestoreArrayRead(S_loc, &sh));
  CELLFSI_PETSC(DMRestoreLocalVector(fluid.dm(), &U_loc));
  CELLFSI_PETSC(DMRestoreLocalVector(dm_scalar, &S_loc));
  if (Nu_loc) {
    CELLFSI_PETSC(VecRestoreArrayRead(Nu_loc, &nuh));
    CELLFSI_PETSC(DMRestoreLocalVector(dm_scalar, &Nu_loc));
  }

  const std::filesystem::path dir(dir_name);
  std::string name;
  if (size == 1) {
    name = std::string(stem) + ".vts";
    write_atomically(grid, (dir / name).string());
  } else {
    // Every rank writes its piece (a rank without elements none), then rank 0 the index: a failure on any
    // rank is reported on every rank before the index names a missing piece.
    char piece[80];
    std::snprintf(piece, sizeof piece, "%s_p%04d.vts", stem.c_str(), rank);
    int ok = 1;
    std::string error;
    if (n > 0) {
      try {
        write_atomically(grid, (dir / piece).string());
      } catch (const std::exception& ex) {
        ok = 0;
        error = ex.what();
      }
    }
    int all_ok = 0;
    CELLFSI_PETSC(MPI_Allreduce(&ok, &all_ok, 1, MPI_INT, MPI_MIN, fluid.comm()));
    if (!all_ok)
      throw std::runtime_error(error.empty() ? "another rank could not write its fluid piece" : error);
    std::vector<int> all(6 * size);
    CELLFSI_PETSC(MPI_Gather(extent, 6, MPI_INT, all.data(), 6, MPI_INT, 0, fluid.comm()));
    name = std::string(stem) + ".pvts";
    // Rank 0 writes the index; its failure (a full disk) must stop every rank (common/collective.hpp).
    on_rank_zero(fluid.comm(), [&] {
      int whole[6] = {0, 0, 0, 0, 0, 0};
      for (int d = 0; d < D; ++d) whole[2 * d + 1] = patch.knots(d).n_elements() * s;
      std::vector<std::array<int, 6>> extents;
      std::vector<std::string> files;
      for (int r = 0; r < size; ++r) {
        if (all[6 * r + 1] < all[6 * r]) continue;  // no elements on rank r
        std::array<int, 6> e;
        std::copy(all.begin() + 6 * r, all.begin() + 6 * r + 6, e.begin());
        extents.push_back(e);
        char f[80];
        std::snprintf(f, sizeof f, "%s_p%04d.vts", stem.c_str(), r);
        files.emplace_back(f);
      }
      write_pvts((dir / name).string(), whole, extents, files, arrays);
    });
  }
  return name;
}

SectionData FluidSolver::section(double u0, int n_profile) const {
  const FluidSolver& fluid = *this;
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
    PhysicalPoint pp;
    // The gathered state is in natural order: a function's node is its folded control-point index.
    auto evaluate = [&](const Param& xi) {
      physical_point(patch, element_of(patch, xi), xi, 1, bv, mv, pp);
      return interpolate(pp, D, [&](int k, int c) { return U[pp.index[k] * dof + c]; });
    };
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
            const PointValues l = evaluate(xi);
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
      const PointValues l = evaluate(xi);
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
