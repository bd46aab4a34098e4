#include "geometry/patch_vtk.hpp"

#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include <vtkCellArray.h>
#include <vtkDoubleArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkStructuredGrid.h>
#include <vtkXMLPolyDataWriter.h>
#include <vtkXMLStructuredGridWriter.h>

#include "common/file_io.hpp"

namespace cellfsi::geometry {

namespace {

void check_samples(int s) {
  if (s < 1)
    throw std::invalid_argument("patch VTK output: samples per element must be >= 1, got " +
                                std::to_string(s));
}

}  // namespace

void write_vtk_atomically(vtkXMLWriter* writer, const std::string& path) {
  // VTK's file output can fail with no reason recorded (a full disk ends as a failed pipeline request, after
  // a printed traceback): the writer fills a string, and the file is written from it with every write
  // checked. The string costs one file's size, briefly.
  const std::filesystem::path parent = std::filesystem::path(path).parent_path();
  if (!parent.empty() && !std::filesystem::is_directory(parent))
    throw_write_error(path, "folder '" + parent.string() + "' does not exist");
  writer->WriteToOutputStringOn();
  if (writer->Write() != 1 || writer->GetErrorCode() != 0)
    throw_write_error(path, "the VTK writer failed (error code " + std::to_string(writer->GetErrorCode()) + ")");
  const std::string text = writer->GetOutputString();
  writer->WriteToOutputStringOff();
  write_file_atomically(path, text, false);
}

std::vector<double> sample_values(const KnotVector& kv, int s) {
  std::vector<double> u;
  for (int e = 0; e < kv.n_elements(); ++e)
    for (int k = 0; k < s; ++k)
      u.push_back(kv.element_begin(e) + (kv.element_end(e) - kv.element_begin(e)) * k / s);
  u.push_back(kv.b());
  return u;
}

std::vector<Param> sample_grid(const Patch& patch, int samples_per_element) {
  check_samples(samples_per_element);
  std::vector<double> u[3] = {{0.0}, {0.0}, {0.0}};
  for (int d = 0; d < patch.param_dim(); ++d) u[d] = sample_values(patch.knots(d), samples_per_element);
  std::vector<Param> xi;
  xi.reserve(u[0].size() * u[1].size() * u[2].size());
  for (double c : u[2])
    for (double b : u[1])
      for (double a : u[0]) xi.push_back({a, b, c});
  return xi;
}

void write_patch_vts(const Patch& patch, const std::string& path, int samples_per_element,
                     const std::vector<PointField>& fields) {
  check_samples(samples_per_element);
  const int P = patch.param_dim();
  std::vector<double> u[3] = {{0.0}, {0.0}, {0.0}};
  for (int d = 0; d < P; ++d) u[d] = sample_values(patch.knots(d), samples_per_element);
  const int n0 = u[0].size(), n1 = u[1].size(), n2 = u[2].size();

  vtkNew<vtkStructuredGrid> grid;
  grid->SetDimensions(n0, n1, n2);
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();  // a 5e-7 cm membrane at 1e-3 cm needs more than float's 7 digits
  points->SetNumberOfPoints(static_cast<vtkIdType>(n0) * n1 * n2);
  vtkNew<vtkDoubleArray> xi;
  xi->SetName("parametric");
  xi->SetNumberOfComponents(3);
  xi->SetNumberOfTuples(points->GetNumberOfPoints());
  vtkNew<vtkDoubleArray> jac;
  jac->SetName("map_jacobian");  // det dx/dxi of the map, not the deformation's J (solid output)
  jac->SetNumberOfTuples(points->GetNumberOfPoints());
  const bool volume = P == patch.physical_dim();
  BasisValues bv;
  MapValues mv;
  vtkIdType id = 0;
  for (int k = 0; k < n2; ++k)
    for (int j = 0; j < n1; ++j)
      for (int i = 0; i < n0; ++i, ++id) {
        const Param p{u[0][i], u[1][j], u[2][k]};
        patch.basis(p, 1, bv);
        patch.map(bv, mv);
        points->SetPoint(id, mv.x.data());
        xi->SetTuple3(id, p[0], p[1], p[2]);
        if (volume) jac->SetValue(id, mv.dx.topLeftCorner(P, P).determinant());
      }
  grid->SetPoints(points);
  grid->GetPointData()->AddArray(xi);
  if (volume) grid->GetPointData()->AddArray(jac);
  for (const PointField& f : fields) {
    if (f.components < 1 ||
        f.values.size() != static_cast<size_t>(f.components * points->GetNumberOfPoints()))
      throw std::invalid_argument("write_patch_vts: field '" + f.name + "' has " +
                                  std::to_string(f.values.size()) + " values for " +
                                  std::to_string(points->GetNumberOfPoints()) + " points");
    vtkNew<vtkDoubleArray> a;
    a->SetName(f.name.c_str());
    a->SetNumberOfComponents(f.components);
    a->SetNumberOfTuples(points->GetNumberOfPoints());
    for (vtkIdType i = 0; i < points->GetNumberOfPoints(); ++i)
      a->SetTuple(i, f.values.data() + f.components * i);
    grid->GetPointData()->AddArray(a);
  }

  vtkNew<vtkXMLStructuredGridWriter> writer;
  writer->SetInputData(grid);
  write_vtk_atomically(writer, path);
}

void write_patch_elements_vtp(const Patch& patch, const std::string& path, int samples_per_element) {
  check_samples(samples_per_element);
  const int P = patch.param_dim();
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  vtkNew<vtkCellArray> lines;
  BasisValues bv;
  MapValues mv;
  auto add_line = [&](int along, const Param& fixed) {
    const std::vector<double> u = sample_values(patch.knots(along), samples_per_element);
    std::vector<vtkIdType> ids;
    for (double t : u) {
      Param p = fixed;
      p[along] = t;
      patch.basis(p, 0, bv);
      patch.map(bv, mv);
      ids.push_back(points->InsertNextPoint(mv.x.data()));
    }
    lines->InsertNextCell(static_cast<vtkIdType>(ids.size()), ids.data());
  };
  if (P == 1) {
    add_line(0, {0, 0, 0});
  } else {
    // Lines along direction `along` through every combination of breakpoints of the other directions.
    for (int along = 0; along < P; ++along) {
      int others[2], n_o = 0;
      for (int d = 0; d < P; ++d)
        if (d != along) others[n_o++] = d;
      const std::vector<double> b0 = patch.knots(others[0]).breakpoints();
      const std::vector<double> b1 =
          n_o > 1 ? patch.knots(others[1]).breakpoints() : std::vector<double>{0.0};
      for (double v1 : b1)
        for (double v0 : b0) {
          Param fixed{0, 0, 0};
          fixed[others[0]] = v0;
          if (n_o > 1) fixed[others[1]] = v1;
          add_line(along, fixed);
        }
    }
  }
  vtkNew<vtkPolyData> poly;
  poly->SetPoints(points);
  poly->SetLines(lines);
  vtkNew<vtkXMLPolyDataWriter> writer;
  writer->SetInputData(poly);
  write_vtk_atomically(writer, path);
}

void write_pvd(const std::string& path, const std::vector<PvdEntry>& entries) {
  std::ostringstream os;
  os << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" "
        "byte_order=\"LittleEndian\">\n"
     << "  <Collection>\n"
     << std::setprecision(17);
  for (const auto& e : entries) {
    os << "    <DataSet timestep=\"" << e.time << "\" part=\"" << e.part << "\"";
    if (!e.name.empty()) os << " name=\"" << e.name << "\"";
    os << " file=\"" << e.file << "\"/>\n";
  }
  os << "  </Collection>\n</VTKFile>\n";
  write_file_atomically(path, os.str(), false);
}

}  // namespace cellfsi::geometry
