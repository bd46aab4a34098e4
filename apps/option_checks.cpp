// See option_checks.hpp.
#include "apps/option_checks.hpp"

#include <petscsys.h>

#include <cctype>
#include <map>
#include <sstream>
#include <stdexcept>

#include "common/petsc_error.hpp"
#include "coupling/solver_policy.hpp"

namespace cellfsi::app {

namespace {

/// Whether PETSc may not have read `name` yet at `when`: the coupled solve's options (the KSP -coupling_) are
/// read when the coupling loop is created; its subdomain solvers', factorisation packages' (MUMPS,
/// SuperLU_DIST, ...) and cellfsi_fourier's region LU's only at the first solve.
bool maybe_unread(const std::string& name, OptionCheck when) {
  auto starts = [&](const char* p) { return name.rfind(p, 0) == 0; };
  if (when == OptionCheck::after_first_step) return false;
  // The first step replaced the automatic choice of preconditioner (reported on the console); the options of
  // the one it replaced were checked against it before the first step and never read.
  if (when == OptionCheck::after_fallback) return coupling::option_of_replaced_solver(name);
  if (when == OptionCheck::before_coupling && starts("coupling_")) return true;
  if (when == OptionCheck::before_first_step && coupling::read_at_first_solve(name)) return true;
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
  std::string first, renamed;
  for (PetscInt i = 0; i < n && first.empty(); ++i) {
    if (!coupling::renamed_option(names[i]).empty()) {
      first = names[i];
      renamed = coupling::renamed_option(names[i]);
    } else if (!maybe_unread(names[i], when)) {
      first = names[i];
    }
  }
  CELLFSI_PETSC(PetscOptionsLeftRestore(nullptr, &n, &names, &values));
  if (!renamed.empty())
    throw std::invalid_argument(
        "option -" + first + " was renamed -" + renamed + " in cellfsi 0.2 (docs/options.md)" +
        (first == "coupling_solver"
             ? ": -coupling_solver band is -coupling_pc_type cellfsi_band, fourier is cellfsi_fourier, fluid is "
               "a PETSc PC such as asm (with -coupling_ksp_*, -coupling_sub_* options), auto is the default "
               "(no option)"
             : ""));
  // The region's LU of its dimension may read no factorisation options (coupling::region_option_unread).
  PetscInt dim = 2;
  PetscBool region_pc_given = PETSC_FALSE;
  CELLFSI_PETSC(PetscOptionsGetInt(nullptr, nullptr, "-dim", &dim, nullptr));
  CELLFSI_PETSC(PetscOptionsHasName(nullptr, nullptr, "-coupling_fourier_region_pc_type", &region_pc_given));
  const std::string unread = coupling::region_option_unread(first, static_cast<int>(dim), region_pc_given);
  if (!unread.empty() && when >= OptionCheck::after_first_step)
    throw std::invalid_argument("option -" + first + " was not read: " + unread);
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
                                        const std::string& pc_type) {
  for (const std::string& name : user_options) {
    const std::string why = coupling::option_inapplicable(name, pc_type);
    if (!why.empty()) throw std::invalid_argument("option -" + name + " does not apply: " + why);
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
