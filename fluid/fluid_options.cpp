// FluidOptions: the fluid's option table (common/option_table.hpp; -help lists it) and its checks.
#include <string>
#include <vector>

#include "common/option_table.hpp"
#include "fluid/fluid_solver.hpp"

namespace cellfsi::fluid {

namespace {

std::vector<double> as_list(const Vec3& v, int dim) { return std::vector<double>(v.data(), v.data() + dim); }
Vec3 as_vec(const std::vector<double>& v) {
  return Vec3(v.size() > 0 ? v[0] : 0.0, v.size() > 1 ? v[1] : 0.0, v.size() > 2 ? v[2] : 0.0);
}

/// The table of FluidOptions (the values it fills are o's and the lists'; their current values are the
/// defaults).
void declare(OptionTable& t, FluidOptions& o, int dim, std::vector<double>& force,
             std::vector<std::vector<double>>& walls) {
  const auto count = [dim] { return dim; };
  t.real("density", o.density, "rho_1 [g/cm^3]", material(1e-6, 1e3, "[g/cm^3]"))
      .real("viscosity", o.viscosity, "mu [g/(cm s)]", material(1e-8, 1e6, "[g/(cm s)]"))
      .reals("body_force", force, "Body force per volume fx,fy[,fz] [dyn/cm^3]", count, finite("[dyn/cm^3]"))
      .flag("stokes", o.stokes, "Drop convection (Stokes flow)")
      .real("rho_inf", o.rho_inf, "Generalized-alpha spectral radius at infinity, [0, 1]", between(0, 1))
      .real("c_i", o.c_i, "C_I of tau_M (equal_order)", positive())
      .text("space", o.space,
            "The velocity-pressure space: equal_order (the paper's VMS, with s_I) or div_conforming "
            "(divergence-free velocity pointwise, no s_I; docs/fluid.md)",
            {"equal_order", "div_conforming"})
      .integer("dc_degree", o.dc_degree, "div_conforming: the pressure degree k' (velocity k' + 1 along its own axis)",
               int_between(2, 3))
      .real("dc_penalty", o.dc_penalty,
            "div_conforming: Nitsche penalty constant C_pen of C_pen nu (k'+1)^2/h",
            {[](const double& v) { return v > 2 && v <= 1e6; }, "> 2 ... 1e6 (coercivity: above 2)"})
      .text(
          "mat_type_jacobian", o.jacobian_type,
          "PETSc matrix type of the Jacobian: baij (one block per control point, the fast insertion) or aij",
          {"baij", "aij"})
      .flag("pressure_null_space", o.pressure_null_space,
            "Give the linear solver the constant pressure as the Jacobian's null space (MatNullSpace) "
            "instead of "
            "pinning one pressure control value");
  const char axes[3] = {'x', 'y', 'z'};
  for (int d = 0; d < dim; ++d)
    for (int s = 0; s < 2; ++s)
      t.reals(std::string("wall_velocity_") + axes[d] + std::to_string(s), walls[2 * d + s],
              "Velocity of the wall at the start (0) or end (1) of this direction [cm/s]", count,
              finite("[cm/s]"));
}

}  // namespace

void FluidOptions::set_from_options(int dim) {
  std::vector<double> force = as_list(body_force, dim);
  std::vector<std::vector<double>> walls(6);
  for (int d = 0; d < dim; ++d)
    for (int s = 0; s < 2; ++s) walls[2 * d + s] = as_list(wall_velocity[d][s], dim);
  OptionTable t("Fluid (VMS Navier-Stokes; CGS units)", "fluid_");
  declare(t, *this, dim, force, walls);
  t.read();
  body_force = as_vec(force);
  for (int d = 0; d < dim; ++d)
    for (int s = 0; s < 2; ++s) wall_velocity[d][s] = as_vec(walls[2 * d + s]);
  validate();
}

void FluidOptions::validate() const {
  // The table's ranges, for settings made in code; dt is the scene's option.
  if (!(dt > 0)) bad_option("dt", option_value_text(dt), "> 0 [s]");
  FluidOptions o = *this;
  std::vector<double> force;
  std::vector<std::vector<double>> walls(6);
  OptionTable t("Fluid", "fluid_");
  declare(t, o, 3, force, walls);
  t.check();
}

}  // namespace cellfsi::fluid
