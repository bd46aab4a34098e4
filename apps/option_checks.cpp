// See option_checks.hpp.
#include "apps/option_checks.hpp"

#include <petscsys.h>

#include <cctype>
#include <map>
#include <sstream>
#include <stdexcept>

#include "common/petsc_error.hpp"

namespace cellfsi::app {

namespace {

/// Whether PETSc may not have read `name` yet at `when`: the coupling loop's solver options are read when it
/// is created; factorisation packages' options (MUMPS, SuperLU_DIST, ...) and convergence reports only at
/// the first solve.
bool maybe_unread(const std::string& name, OptionCheck when) {
  if (when == OptionCheck::after_first_step) return false;
  // The first step replaced the solver (reported on the console): the band solver's region held most of
  // the domain, or the Fourier solver chosen by auto found the operator not uniform. The replaced solver's
  // options were checked against it before the first step and never read.
  if (when == OptionCheck::after_fallback)
    return name.rfind("coupling_band_", 0) == 0 || name.rfind("coupling_fourier_", 0) == 0;
  if (when == OptionCheck::before_coupling &&
      (name.rfind("coupling_band_", 0) == 0 || name.rfind("coupling_fourier_", 0) == 0))
    return true;
  // The Fourier solver's region LU is created at the first solve.
  if (when == OptionCheck::before_first_step && name.rfind("coupling_fourier_region_", 0) == 0) return true;
  for (const char* late : {"mat_mumps_", "mat_superlu", "mat_strumpack", "converged_reason", "ksp_view"})
    if (name.find(late) != std::string::npos) return true;
  return false;
}

}  // namespace

/// Fails on options nobody read (a misspelt key must not be silently ignored), skipping those PETSc may read
/// later than `when`.
void reject_unknown_options(OptionCheck when) {
  PetscInt n = 0;
  char** names = nullptr;
  char** values = nullptr;
  CELLFSI_PETSC(PetscOptionsLeftGet(nullptr, &n, &names, &values));
  std::string first;
  for (PetscInt i = 0; i < n && first.empty(); ++i)
    if (!maybe_unread(names[i], when)) first = names[i];
  CELLFSI_PETSC(PetscOptionsLeftRestore(nullptr, &n, &names, &values));
  if (!first.empty())
    throw std::invalid_argument("unknown option -" + first +
                                " (misspelt? run with -help for the valid options)" +
                                (when >= OptionCheck::after_first_step
                                     ? " (found after the first time step, when every solver had read "
                                       "its options)"
                                     : ""));
}

/// Names (without the dash) of the options in the database now: the user's command line and scene file.
std::vector<std::string> option_names() {
  char* all = nullptr;
  CELLFSI_PETSC(PetscOptionsGetAll(nullptr, &all));
  std::vector<std::string> names;
  std::istringstream is(all ? all : "");
  for (std::string w; is >> w;)
    if (w.size() > 1 && w[0] == '-' && std::isalpha(static_cast<unsigned char>(w[1])))
      names.push_back(w.substr(1));
  CELLFSI_PETSC(PetscFree(all));
  return names;
}

/// See option_checks.hpp.
void reject_inapplicable_solver_options(const std::vector<std::string>& user_options,
                                        coupling::CouplingSolver solver) {
  using coupling::CouplingSolver;
  const char* in_use = solver == CouplingSolver::band      ? "band"
                       : solver == CouplingSolver::fourier ? "fourier"
                                                           : "fluid";
  for (const std::string& name : user_options) {
    // The coupling loop is a coupled run's nonlinear iteration, whichever linear solver it uses.
    if (name.rfind("fluid_snes_", 0) == 0)
      throw std::invalid_argument("option -" + name +
                                  " does not apply: in a coupled run the nonlinear iteration is the coupling "
                                  "loop (-coupling_tolerance, -coupling_max_iterations, -coupling_monitor, "
                                  "-coupling_acceleration); -fluid_snes_ options act on runs without cells");
    if (solver != CouplingSolver::fluid) {
      if (name == "fluid_mat_type_jacobian") continue;  // the matrix type applies to every solver
      for (const char* p : {"fluid_ksp_", "fluid_pc_", "fluid_sub_", "fluid_mat_"})
        if (name.rfind(p, 0) == 0)
          throw std::invalid_argument(
              "option -" + name + " does not apply: this coupled run solves with -coupling_solver " + in_use +
              ", which has its own options under -coupling_" + in_use + "_ (e.g. -coupling_" + in_use +
              "_ksp_monitor" +
              (solver == CouplingSolver::band
                   ? ", -coupling_band_mat_mumps_icntl_14 40, -coupling_band_schur_mat_mumps_icntl_35 1"
                   : ", -coupling_fourier_region_mat_mumps_icntl_14 40") +
              "); for the fluid's KSP and PC options use -coupling_solver fluid");
    }
    // The band's refresh interval and region margin also pace and bound the Fourier solver's refreshes.
    const bool band_option = name.rfind("coupling_band_", 0) == 0;
    if (band_option && solver != CouplingSolver::band &&
        !(solver == CouplingSolver::fourier &&
          (name == "coupling_band_refresh_steps" || name == "coupling_band_margin")))
      throw std::invalid_argument("option -" + name + " does not apply: this coupled run solves with " +
                                  "-coupling_solver " + in_use +
                                  (solver == CouplingSolver::fluid
                                       ? " (asked for, or because the band solver needs one fluid rank and a "
                                         "BAIJ Jacobian)"
                                       : ""));
    if (name.rfind("coupling_fourier_", 0) == 0 && solver != CouplingSolver::fourier)
      throw std::invalid_argument("option -" + name + " does not apply: this coupled run solves with " +
                                  "-coupling_solver " + in_use);
  }
}

/// See option_checks.hpp.
std::string split_option_differences(const std::string& fluid_side, const std::string& solid_side) {
  auto map = [](const std::string& text) {
    std::map<std::string, std::string> m;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) {
      const auto colon = line.find(": ");
      if (line.empty() || line[0] == '#' || colon == std::string::npos) continue;
      const std::string key = line.substr(0, colon);
      const bool shapes_bodies = key.rfind("solid_", 0) == 0 || key.rfind("domain", 0) == 0 ||
                                 key.rfind("channel_", 0) == 0 || key == "dim" || key == "fluid_elements" ||
                                 key == "fluid_degree" || key == "coupling_max_mesh_ratio";
      const bool time_stepping = key == "dt" || key == "final_time";
      if ((shapes_bodies || time_stepping) && key != "solid_ranks") m[key] = line.substr(colon + 2);
    }
    return m;
  };
  const auto f = map(fluid_side), sd = map(solid_side);
  std::string out;
  auto add = [&](const std::string& k, const std::string& a, const std::string& b) {
    out += (out.empty() ? "" : "; ") + k + ": " + a + " -> " + b;
  };
  for (const auto& [k, v] : f) {
    const auto it = sd.find(k);
    if (it == sd.end())
      add(k, v, "(not given)");
    else if (it->second != v)
      add(k, v, it->second);
  }
  for (const auto& [k, v] : sd)
    if (f.find(k) == f.end()) add(k, "(not given)", v);
  return out;
}

}  // namespace cellfsi::app
