// cellfsi-geometry: builds the Eulerian domains and cell patches of every experiment of the paper (Casquero,
// Bona-Casas & Gomez 2017) at the paper's resolutions, writes them to VTK for ParaView and prints their shape
// measures. It is the default scene until the FSI scenes exist.
//
//   cellfsi-geometry                              # writes out/geometry/geometry.pvd and its pieces
//   cellfsi-geometry -output_dir /tmp/g -samples 6
//   cellfsi-geometry -help                        # lists the options with their defaults
#include <petscsys.h>

#include <cstdio>
#include <filesystem>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/option_table.hpp"
#include "common/petsc_error.hpp"
#include "geometry/builders.hpp"
#include "geometry/measures.hpp"
#include "geometry/patch_vtk.hpp"

namespace geo = cellfsi::geometry;

namespace {

struct Options {
  std::string output_dir = "out/geometry";
  int samples = 4;       // sampling intervals per element for cell patches
  int mesh_samples = 1;  // per element for the Eulerian meshes (1: the element grid itself)
  bool three_d = true;
};

/// Reads and checks the options (an option table: -help lists them).
void read_options(Options& o) {
  cellfsi::OptionTable t("cellfsi-geometry: the paper's domains and cells written to VTK");
  t.text("output_dir", o.output_dir, "Folder for geometry.pvd and its pieces (created if missing)")
      .integer("samples", o.samples, "Sampling intervals per element for the cell patches",
               cellfsi::at_least(1))
      .integer("mesh_samples", o.mesh_samples, "Sampling intervals per element for the Eulerian meshes",
               cellfsi::at_least(1))
      .flag("three_d", o.three_d, "Also write the 3D compound capsule scene (64^3 box)");
  t.read();
}

/// Collects written pieces into one .pvd, one part per piece.
class Collection {
 public:
  explicit Collection(std::filesystem::path dir) : dir_(std::move(dir)) {}
  void add(const std::string& name, const geo::Patch& patch, int samples, bool element_lines) {
    geo::write_patch_vts(patch, (dir_ / (name + ".vts")).string(), samples);
    entries_.push_back({name + ".vts", 0.0, static_cast<int>(entries_.size()), name});
    if (element_lines) {
      geo::write_patch_elements_vtp(patch, (dir_ / (name + "_elements.vtp")).string(), 2 * samples);
      entries_.push_back(
          {name + "_elements.vtp", 0.0, static_cast<int>(entries_.size()), name + "_elements"});
    }
  }
  void write() const { geo::write_pvd((dir_ / "geometry.pvd").string(), entries_); }
  size_t size() const { return entries_.size(); }

 private:
  std::filesystem::path dir_;
  std::vector<geo::PvdEntry> entries_;
};

void print_membrane(const char* name, const geo::Patch& membrane) {
  const geo::MembraneShape s = geo::membrane_shape(membrane);
  const int D = membrane.physical_dim();
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD, "  %-28s %-9s %12.5e %12.5e %8.4f %11.4e %4d\n", name,
                            D == 2 ? "membrane" : "shell", s.enclosed, s.boundary, s.swelling,
                            s.effective_radius, membrane.n_elements()));
}

void print_body(const char* name, const geo::Patch& body) {
  const geo::RegionMoments m = geo::patch_moments(body);
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD, "  %-28s %-9s %12.5e %12s %8s %11s %4d\n", name, "bulk",
                            m.measure, "-", "-", "-", body.n_elements()));
}

void run(const Options& o) {
  const std::filesystem::path dir(o.output_dir);
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir))
    throw std::runtime_error("-output_dir '" + o.output_dir + "' cannot be created: " + ec.message());
  Collection out(dir);
  const double half_pi = std::numbers::pi / 2;
  const int s = static_cast<int>(o.samples), ms = static_cast<int>(o.mesh_samples);

  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD,
                            "cellfsi-geometry: writing the paper's domains and cells to %s\n",
                            o.output_dir.c_str()));
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD, "  %-28s %-9s %12s %12s %8s %11s %4s\n",
                            "patch (paper section)", "kind", "area/vol", "perim/surf", "Delta", "R0 [cm]",
                            "elements"));

  // Sec. 3.3-3.5: capsule in shear flow. 0.0024 x 0.0012 cm, periodic in x, 256 x 128 cubic; hollow ellipse
  // a = 2e-4, b = 1e-4, h = 5e-7 cm, 1 x 208 quadratic, long axis across the flow.
  out.add("shear_box", geo::rectangle(0.0024, 0.0012, 256, 128, 3, {true, false}), ms, false);
  const geo::Patch capsule =
      geo::hollow_ellipse(2e-4, 1e-4, 5e-7, 208, 2, geo::Vec3(0.0012, 0.0006, 0), half_pi);
  out.add("capsule", capsule, s, true);
  print_membrane("capsule (3.3)", capsule);
  const geo::Patch rbc_shear = geo::biconcave_rbc(5e-7, 208, 2, geo::Vec3(0.0012, 0.0006, 0), half_pi);
  print_membrane("biconcave capsule (3.5)", rbc_shear);

  // Sec. 3.6: 2D compound capsule: the capsule above with a circular inclusion, here r = 5e-5 cm.
  const geo::Patch inclusion = geo::bulky_ellipse(5e-5, 5e-5, 10, 48, 2, geo::Vec3(0.0012, 0.0006, 0));
  out.add("inclusion", inclusion, s, true);
  print_body("inclusion r=5e-5 (3.6)", inclusion);

  // Sec. 4.1/4.3: RBCs in a 0.003 x 0.001 cm channel, periodic in x, 384 x 128 cubic; six RBCs (1 x 328
  // quadratic) evenly spaced, long side across the flow.
  out.add("rbc_channel", geo::rectangle(0.003, 0.001, 384, 128, 3, {true, false}, geo::Vec3(0.003, 0, 0)), ms,
          false);
  for (int k = 0; k < 6; ++k) {
    const geo::Patch rbc =
        geo::biconcave_rbc(5e-7, 328, 2, geo::Vec3(0.003 + 0.0005 * (k + 0.5), 0.0005, 0), half_pi);
    out.add("rbc_" + std::to_string(k), rbc, s, k == 0);
    if (k == 0) print_membrane("RBC (4.1)", rbc);
  }

  // Sec. 4.4: CTC through a narrowing (384 x 128 cubic); compound capsule: membrane r = 5e-4 cm (1 x 768),
  // nucleus r = 2e-4 cm (40 x 192), both quadratic, upstream of the throat.
  const geo::NarrowingChannel ch;
  const geo::Vec3 ctc_offset(0, 0.003, 0), ctc_centre = geo::Vec3(0.0008, 0, 0) + ctc_offset;
  out.add("narrowing_channel", geo::narrowing_channel(ch, 384, 128, 3), ms, false);
  // (the channel is shifted below so the scenes do not overlap in ParaView)
  const geo::Patch ctc_membrane = geo::hollow_ellipse(5e-4, 5e-4, 5e-7, 768, 2, ctc_centre);
  const geo::Patch nucleus = geo::bulky_ellipse(2e-4, 2e-4, 40, 192, 2, ctc_centre);
  out.add("ctc_membrane", ctc_membrane, s, true);
  out.add("ctc_nucleus", nucleus, s, true);
  print_membrane("CTC membrane (4.4)", ctc_membrane);
  print_body("CTC nucleus (4.4)", nucleus);

  if (o.three_d) {
    // Sec. 3.6, 3D: cube of side 0.0012 cm (64^3 quadratic), ellipsoid shell 3e-4 x 2e-4 x 2e-4 cm (3072
    // elements), sphere r = 1e-4 cm (7168 elements).
    const geo::Vec3 c(0.0006, 0.0006, 0.0006), shift(0.0, -0.002, 0.0);
    out.add("cube", geo::box(0.0012, 0.0012, 0.0012, 64, 64, 64, 2, {true, true, false}, shift), ms, false);
    const geo::Patch shell = geo::hollow_ellipsoid(3e-4, 2e-4, 2e-4, 5e-7, 32, 96, 2, c + shift);
    const geo::Patch sphere = geo::solid_ellipsoid(1e-4, 1e-4, 1e-4, 7, 32, 32, 2, c + shift);
    out.add("shell_3d", shell, s, false);
    out.add("sphere_3d", sphere, s, false);
    print_membrane("ellipsoid shell (3.6)", shell);
    print_body("sphere (3.6)", sphere);
  }
  out.write();
  CELLFSI_PETSC(PetscPrintf(PETSC_COMM_WORLD, "wrote %zu pieces; open %s in ParaView\n", out.size(),
                            (dir / "geometry.pvd").c_str()));
}

}  // namespace

int main(int argc, char** argv) {
  PetscCall(PetscInitialize(&argc, &argv, nullptr, nullptr));
  int status = 0;
  try {
    Options o;
    read_options(o);
    PetscBool help = PETSC_FALSE;
    PetscCall(PetscOptionsHasName(nullptr, nullptr, "-help", &help));
    // Unknown options are errors, not silently ignored.
    PetscInt n_left = 0;
    char** names = nullptr;
    char** values = nullptr;
    PetscCall(PetscOptionsLeftGet(nullptr, &n_left, &names, &values));
    if (n_left > 0) {
      std::string msg =
          "unknown option -" + std::string(names[0]) + " (run with -help for the valid options)";
      PetscCall(PetscOptionsLeftRestore(nullptr, &n_left, &names, &values));
      throw std::invalid_argument(msg);
    }
    PetscCall(PetscOptionsLeftRestore(nullptr, &n_left, &names, &values));
    if (!help) {
      // The demo is serial: under mpirun only rank 0 builds and writes (no two ranks write one file).
      PetscMPIInt rank = 0;
      PetscCallMPI(MPI_Comm_rank(PETSC_COMM_WORLD, &rank));
      if (rank == 0) run(o);
    }
  } catch (const std::exception& e) {
    PetscCall(PetscFPrintf(PETSC_COMM_WORLD, PETSC_STDERR, "cellfsi-geometry: error: %s\n", e.what()));
    status = 1;
  }
  PetscCall(PetscFinalize());
  return status;
}
