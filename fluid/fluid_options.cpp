// FluidOptions: reading (PETSc options, so -help lists them) and validation.
#include <sstream>
#include <stdexcept>

#include "common/petsc_error.hpp"
#include "fluid/fluid_solver.hpp"

namespace cellfsi::fluid {

namespace {

[[noreturn]] void bad_option(const std::string& name, const std::string& value, const std::string& valid) {
  throw std::invalid_argument("option -" + name + " = " + value + " is invalid; valid: " + valid);
}

std::string str(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

/// Raw option values (read in a PETSc options block, so -help lists them), checked afterwards.
struct RawFluidOptions {
  PetscReal density, viscosity, rho_inf, c_i;
  PetscReal body_force[4] = {0, 0, 0, 0};
  PetscInt n_body_force = 0;
  PetscBool body_force_set = PETSC_FALSE, stokes = PETSC_FALSE;
  PetscReal wall[3][2][4] = {};
  PetscInt n_wall[3][2] = {};
  PetscBool wall_set[3][2] = {};
};

PetscErrorCode read_fluid_options(RawFluidOptions& r, int dim) {
  PetscFunctionBeginUser;
  PetscOptionsBegin(PETSC_COMM_WORLD, nullptr, "Fluid (VMS Navier-Stokes; CGS units)", nullptr);
  PetscCall(PetscOptionsReal("-fluid_density", "rho_1 [g/cm^3]", nullptr, r.density, &r.density, nullptr));
  PetscCall(
      PetscOptionsReal("-fluid_viscosity", "mu [g/(cm s)]", nullptr, r.viscosity, &r.viscosity, nullptr));
  r.n_body_force = 4;
  PetscCall(PetscOptionsRealArray("-fluid_body_force", "Body force per volume fx,fy[,fz] [dyn/cm^3]", nullptr,
                                  r.body_force, &r.n_body_force, &r.body_force_set));
  PetscCall(PetscOptionsBool("-fluid_stokes", "Drop convection (Stokes flow)", nullptr, r.stokes, &r.stokes,
                             nullptr));
  PetscCall(PetscOptionsReal("-fluid_rho_inf", "Generalized-alpha spectral radius at infinity, [0, 1]",
                             nullptr, r.rho_inf, &r.rho_inf, nullptr));
  PetscCall(PetscOptionsReal("-fluid_c_i", "C_I of tau_M", nullptr, r.c_i, &r.c_i, nullptr));
  const char axes[3] = {'x', 'y', 'z'};
  for (int d = 0; d < dim; ++d)
    for (int s = 0; s < 2; ++s) {
      char name[64];
      std::snprintf(name, sizeof name, "-fluid_wall_velocity_%c%d", axes[d], s);
      r.n_wall[d][s] = 4;
      PetscCall(PetscOptionsRealArray(
          name, "Velocity of the wall at the start (0) or end (1) of this direction [cm/s]", nullptr,
          r.wall[d][s], &r.n_wall[d][s], &r.wall_set[d][s]));
    }
  PetscOptionsEnd();
  PetscFunctionReturn(0);
}

Vec3 vector_option(const std::string& name, const PetscReal* v, PetscInt n, int dim) {
  if (n != dim)
    bad_option(name, std::to_string(n) + " values", std::to_string(dim) + " comma-separated values");
  return Vec3(v[0], v[1], dim == 3 ? v[2] : 0.0);
}

}  // namespace

void FluidOptions::set_from_options(int dim) {
  RawFluidOptions r;
  r.density = density, r.viscosity = viscosity, r.rho_inf = rho_inf, r.c_i = c_i;
  r.stokes = stokes ? PETSC_TRUE : PETSC_FALSE;
  call_reporting_input_errors([&] { return read_fluid_options(r, dim); }, {{"-fluid_density", 'r'},
                                                                           {"-fluid_viscosity", 'r'},
                                                                           {"-fluid_body_force", 'R'},
                                                                           {"-fluid_stokes", 'b'},
                                                                           {"-fluid_rho_inf", 'r'},
                                                                           {"-fluid_c_i", 'r'},
                                                                           {"-fluid_wall_velocity_x0", 'R'},
                                                                           {"-fluid_wall_velocity_x1", 'R'},
                                                                           {"-fluid_wall_velocity_y0", 'R'},
                                                                           {"-fluid_wall_velocity_y1", 'R'},
                                                                           {"-fluid_wall_velocity_z0", 'R'},
                                                                           {"-fluid_wall_velocity_z1", 'R'}});
  density = r.density, viscosity = r.viscosity, rho_inf = r.rho_inf, c_i = r.c_i;
  stokes = r.stokes == PETSC_TRUE;
  if (r.body_force_set) body_force = vector_option("fluid_body_force", r.body_force, r.n_body_force, dim);
  const char axes[3] = {'x', 'y', 'z'};
  for (int d = 0; d < dim; ++d)
    for (int s = 0; s < 2; ++s)
      if (r.wall_set[d][s])
        wall_velocity[d][s] = vector_option(std::string("fluid_wall_velocity_") + axes[d] + std::to_string(s),
                                            r.wall[d][s], r.n_wall[d][s], dim);
  validate();
}

void FluidOptions::validate() const {
  if (!(density > 0)) bad_option("fluid_density", str(density), "> 0 [g/cm^3]");
  if (!(viscosity > 0)) bad_option("fluid_viscosity", str(viscosity), "> 0 [g/(cm s)]");
  if (!(rho_inf >= 0 && rho_inf <= 1)) bad_option("fluid_rho_inf", str(rho_inf), "0 <= rho_inf <= 1");
  if (!(dt > 0)) bad_option("dt", str(dt), "> 0 [s]");
  if (!(c_i > 0)) bad_option("fluid_c_i", str(c_i), "> 0");
}

}  // namespace cellfsi::fluid
