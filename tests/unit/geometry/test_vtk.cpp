// VTK output: the written files read back with the patch's points; the .pvd collection lists them.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include <vtkDataArray.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkStructuredGrid.h>
#include <vtkXMLPolyDataReader.h>
#include <vtkXMLStructuredGridReader.h>

#include "geometry/builders.hpp"
#include "geometry/patch_vtk.hpp"

using namespace cellfsi::geometry;
namespace fs = std::filesystem;

TEST(PatchVtk, StructuredGridAndElementLinesReadBack) {
  const fs::path dir = fs::temp_directory_path() / "cellfsi_test_vtk";
  fs::create_directories(dir);
  const Patch e = hollow_ellipse(2e-4, 1e-4, 5e-7, 16, 2);
  write_patch_vts(e, (dir / "e.vts").string(), 3);
  write_patch_elements_vtp(e, (dir / "e_elements.vtp").string(), 4);
  write_pvd((dir / "g.pvd").string(), {{"e.vts", 0.0, 0, "ellipse"}, {"e_elements.vtp", 0.0, 1, "elements"}});

  vtkNew<vtkXMLStructuredGridReader> reader;
  reader->SetFileName((dir / "e.vts").c_str());
  reader->Update();
  vtkStructuredGrid* grid = reader->GetOutput();
  int dims[3];
  grid->GetDimensions(dims);
  EXPECT_EQ(dims[0], 1 * 3 + 1);
  EXPECT_EQ(dims[1], 16 * 3 + 1);
  EXPECT_EQ(dims[2], 1);
  // Point (i=2, j=5) is the patch at xi = (2/3, 5/48).
  double x[3];
  grid->GetPoint(2 + dims[0] * 5, x);
  const Vec3 ref = e.point({2.0 / 3.0, 5.0 / 48.0, 0});
  EXPECT_LT((Vec3(x[0], x[1], x[2]) - ref).norm(), 1e-18);
  EXPECT_NE(grid->GetPointData()->GetArray("map_jacobian"), nullptr);

  vtkNew<vtkXMLPolyDataReader> lines;
  lines->SetFileName((dir / "e_elements.vtp").c_str());
  lines->Update();
  // Element lines: 2 lines along the angle (at r = 0, 1) and 17 across (one per angular breakpoint).
  EXPECT_EQ(lines->GetOutput()->GetNumberOfLines(), 2 + 17);

  std::ifstream pvd(dir / "g.pvd");
  std::stringstream ss;
  ss << pvd.rdbuf();
  EXPECT_NE(ss.str().find("file=\"e_elements.vtp\""), std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "g.pvd.tmp"));
  fs::remove_all(dir);
}

TEST(PatchVtk, UnwritablePathIsAnError) {
  const Patch r = rectangle(1, 1, 2, 2, 2);
  EXPECT_THROW(write_patch_vts(r, "/nonexistent-dir/x.vts"), std::runtime_error);
  EXPECT_THROW(write_pvd("/nonexistent-dir/x.pvd", {}), std::runtime_error);
}
