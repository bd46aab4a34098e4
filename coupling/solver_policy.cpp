// See solver_policy.hpp.
#include "coupling/solver_policy.hpp"

#include <petscpc.h>

namespace cellfsi::coupling {

namespace {

bool starts_with(const std::string& s, const char* p) { return s.rfind(p, 0) == 0; }

}  // namespace

LinearSolverOptions linear_solver_defaults(int dim) {
  LinearSolverOptions o;
  if (dim != 3) return o;
  // The re-assembled region's margin: 4 elements in 2D (measured with cellfsi_band at 256 x 128: margins 2
  // and 6 were slower), 1 in 3D (cellfsi_fourier at 32^3, 12 steps: the Jacobian 1.43 s per step against 2.18
  // with 4, the whole step 6 % faster; docs/design.md §8).
  o.region_margin = 1;
  // No whole Jacobian after the first step in 3D (cellfsi_fourier): at the paper's 64^3 on one rank, peak
  // memory 7.2 GB against 14.8 and the Jacobian's refreshes 7x cheaper, the metrics the same to 4e-10
  // (docs/design.md §8). 2D keeps the assembled Jacobian (small there).
  o.bulk_stencil = true;
  // The coupled FGMRES to rtol 1e-2 in 3D: the coupling iterations are those of 1e-5 and the FGMRES
  // iterations half (the compound capsule at 32^3 and 64^3, metrics the same to 3e-6 relative;
  // docs/design.md §8). 2D keeps 1e-5: there 1e-2 costs coupling iterations (4 -> 5-6 per step).
  o.rtol = 1e-2;
  return o;
}

std::optional<bool> pc_type_bulk_stencil(const std::string& pc_type) {
  if (pc_type == solvers::kPCBulk) return true;
  return std::nullopt;
}

std::optional<int> pc_type_refresh_steps(const std::string& pc_type) {
  if (pc_type == solvers::kPCBulk) return 1;
  return std::nullopt;
}

std::vector<std::pair<std::string, std::string>> PetscPCDefaults::options(bool pressure_null_space) {
  std::vector<std::pair<std::string, std::string>> defaults{
      {"-coupling_sub_pc_type", fluid::KrylovDefaults::sub_pc_type},
      {"-coupling_sub_pc_factor_mat_solver_type", fluid::KrylovDefaults::sub_solver}};
  if (pressure_null_space) {
    defaults.emplace_back("-coupling_sub_mat_mumps_icntl_24", "1");
    defaults.emplace_back("-coupling_mat_mumps_icntl_24", "1");
  }
  return defaults;
}

std::string fourier_inapplicable(const geometry::Patch& patch) {
  int walls = 0;
  for (int d = 0; d < patch.param_dim(); ++d)
    if (!patch.knots(d).periodic() && patch.n_control(d) > 1) ++walls;
  if (walls > 1)
    return "the fluid domain has " + std::to_string(walls) + " non-periodic directions (at most 1)";
  if (!geometry::translation_invariant(patch))
    return "the fluid mesh is not uniform along its periodic directions (e.g. the narrowing channel)";
  return "";
}

std::string default_pc_type(const SolverSituation& s) {
  if (s.own_bulk_inverse) return solvers::kPCBulk;
  if (s.baij && s.fourier_inapplicable.empty()) return solvers::kPCFourier;
  if (s.baij && s.fluid_ranks == 1) return solvers::kPCBand;
  return PCASM;
}

std::string fallback_pc_type(bool baij, int fluid_ranks) {
  return default_pc_type({baij, fluid_ranks, "(fell back)", false});
}

int jacobian_copies(const std::string& pc_type, bool partial_jacobian, bool bulk_stencil) {
  // cellfsi_band: the kept part, MUMPS' input copy of it and the whole; cellfsi_fourier: the part away from
  // the cells (unless partial_jacobian is off) and the whole, or with the bulk stencil the whole only while
  // the bulk solver is built (then the rows near the cells).
  if (pc_type == solvers::kPCBand) return 3;
  if (pc_type == solvers::kPCFourier && bulk_stencil) return 1;
  if (pc_type == solvers::kPCFourier) return partial_jacobian ? 2 : 1;
  return 1;
}

MemoryPlan plan_memory(const std::string& pc_type, const LinearSolverOptions& options, bool partial_given,
                       double jacobian_bytes, double available) {
  MemoryPlan plan;
  plan.partial_jacobian = options.partial_jacobian;
  if (pc_type == solvers::kPCFourier && options.partial_jacobian && !options.bulk_stencil && !partial_given &&
      kPartialJacobianFit * jacobian_bytes > available)
    plan.partial_jacobian = false;
  plan.jacobian_copies = jacobian_copies(pc_type, plan.partial_jacobian, options.bulk_stencil);
  return plan;
}

void add_pc_lag_option(OptionTable& t, LinearSolverOptions& l) {
  t.integer(
      "coupling_pc_lag", l.preconditioner_lag,
      "Linear solves between rebuilds of a PETSc PC (not the cellfsi types, which -coupling_refresh_steps "
      "paces)",
      at_least(1));
}

void add_solver_options(OptionTable& t, LinearSolverOptions& l, PCTypeOptions& pc) {
  const LinearSolverOptions in_2d = linear_solver_defaults(2), in_3d = linear_solver_defaults(3);
  t.text("coupling_pc_type", l.pc_type,
         "Preconditioner of the coupled solve, the KSP -coupling_ (FGMRES with the cellfsi types, else "
         "GMRES): cellfsi_fourier (the Jacobian without the cells inverted by FFT, corrected by an LU of the "
         "region around them; a box periodic and uniform in all directions but one, any number of ranks), "
         "cellfsi_band (the Jacobian away from the cells factorised once, the band around them re-solved "
         "exactly; one fluid rank) or any PETSc PC (asm, lu, ...). Not given: cellfsi_fourier where it "
         "applies, else cellfsi_band on one rank, else asm")
      // The cellfsi PC types read their own options (solvers/pc_fourier.hpp, pc_band.hpp: PCSetFromOptions);
      // they are listed and range-checked here too, so that -help and docs/options.md show them with the
      // rest.
      .real(
          "coupling_pc_fourier_threshold", pc.fourier.threshold,
          "cellfsi_fourier: relative deviation of a node's Jacobian rows from the bulk operator that puts it "
          "in the LU-corrected region",
          positive())
      .integer("coupling_pc_fourier_overlap", pc.fourier.overlap,
               "cellfsi_fourier: node layers the LU-corrected region is grown by",
               int_between(0, solvers::RegionOptions::kMaxOverlap))
      .integer(
          "coupling_pc_fourier_region_solves", pc.fourier.region_solves,
          "cellfsi_fourier: region LU solves per application: 2 (region, bulk, region) or 1 (bulk, region)",
          int_between(1, 2))
      .flag(
          "coupling_pc_band_fused", pc.band.fused_solve,
          "cellfsi_band: one MUMPS solve with the Schur complement's inside it (false: two interior solves)")
      .real("coupling_pc_band_blr_tolerance", pc.band.blr_tolerance,
            "cellfsi_band: block low-rank threshold of the kept part's MUMPS factors (0: full rank)",
            {solvers::BandSchurOptions::valid_blr_tolerance, "0 <= tolerance < 1"})
      .flag("coupling_partial_jacobian", l.partial_jacobian,
            "cellfsi_fourier: re-assemble only the Jacobian around the cells, keeping the rest in a second "
            "copy "
            "(false: one copy, the whole Jacobian at every refresh)")
      .flag("coupling_bulk_stencil", l.bulk_stencil,
            "cellfsi_fourier and cellfsi_bulk: no whole Jacobian after the first step: the Krylov products "
            "apply the bulk operator's stencil away from the cells and an assembled matrix of the rows near "
            "them (saves the Jacobian's memory and most of its assembly; an inexact Newton iteration; "
            "default " +
                std::string(in_3d.bulk_stencil ? "true" : "false") + " in 3D and with cellfsi_bulk)")
      .integer("coupling_region_margin", l.region_margin,
               "cellfsi types: elements around the s^h band and immersed points in the re-assembled region "
               "(default " +
                   std::to_string(in_2d.region_margin) + " in 2D, " + std::to_string(in_3d.region_margin) +
                   " in 3D)",
               at_least(0))
      .integer("coupling_refactor_every", l.refactor_every,
               "cellfsi_band: steps between factorisations of the kept part (0: when the cells leave its "
               "region)",
               at_least(0, "(0: only when needed)"))
      .integer(
          "coupling_refresh_steps", l.refresh_steps,
          "cellfsi types: steps between refreshes of the Jacobian and the preconditioner while the s^h "
          "marking stays (it is refreshed whenever the marking moves; default 1 with cellfsi_bulk, whose "
          "space has no marking)",
          at_least(1, "(1: every step)"))
      .integer("coupling_refresh_lag", l.refresh_lag,
               "Coupling iterations between refreshes of the Jacobian (0: only the steps' refreshes; cellfsi "
               "types with their preconditioner, counted since the last refresh, across steps; PETSc PCs the "
               "Jacobian alone, counted within each step, the PC by -coupling_pc_lag)",
               at_least(0, "(0: none inside a step)"));
}

std::string renamed_option(const std::string& name) {
  static const std::vector<std::pair<std::string, std::string>> renamed{
      {"coupling_solver", "coupling_pc_type"},
      {"coupling_fourier_threshold", "coupling_pc_fourier_threshold"},
      {"coupling_fourier_overlap", "coupling_pc_fourier_overlap"},
      {"coupling_fourier_region_solves", "coupling_pc_fourier_region_solves"},
      {"coupling_fourier_partial_jacobian", "coupling_partial_jacobian"},
      {"coupling_band_margin", "coupling_region_margin"},
      {"coupling_band_refresh_steps", "coupling_refresh_steps"},
      {"coupling_band_schur_lag", "coupling_refresh_lag"},
      {"coupling_band_refactor_every", "coupling_refactor_every"}};
  for (const auto& [old_name, new_name] : renamed)
    if (name == old_name) return new_name;
  return "";
}

std::string option_inapplicable(const std::string& name, const std::string& pc_type) {
  // The coupling loop is a coupled run's nonlinear iteration, and its KSP the coupled run's linear solver.
  if (starts_with(name, "fluid_snes_"))
    return "in a coupled run the nonlinear iteration is the coupling loop (-coupling_tolerance, "
           "-coupling_max_iterations, -coupling_monitor, -coupling_acceleration); -fluid_snes_ options act "
           "on "
           "runs without cells";
  if (name != "fluid_mat_type_jacobian")
    for (const char* p : {"fluid_ksp_", "fluid_pc_", "fluid_sub_", "fluid_mat_"})
      if (starts_with(name, p))
        return "a coupled run solves with the KSP -coupling_ (e.g. -" + std::string(kCouplingPrefix) +
               name.substr(6) + "): -fluid_ solver options act on runs without cells";
  // Which PC types read which options: a name, or a prefix (ending in _), and the types.
  enum class Reader { fourier, band, bulk_types, region_types, cellfsi_types, petsc_pcs };
  struct Scope {
    const char* name;
    Reader reader;
  };
  static const Scope kScopes[] = {{"coupling_pc_fourier_", Reader::fourier},
                                  {"coupling_fourier_", Reader::fourier},
                                  {"coupling_partial_jacobian", Reader::fourier},
                                  {"coupling_bulk_stencil", Reader::bulk_types},
                                  {"coupling_pc_band_", Reader::band},
                                  {"coupling_band_", Reader::band},
                                  {"coupling_refactor_every", Reader::band},
                                  {"coupling_region_margin", Reader::region_types},
                                  {"coupling_refresh_steps", Reader::cellfsi_types},

                                  {"coupling_pc_lag", Reader::petsc_pcs}};
  const bool fourier = pc_type == solvers::kPCFourier, band = pc_type == solvers::kPCBand,
             bulk = pc_type == solvers::kPCBulk;
  const std::string in_use = "this coupled run solves with -coupling_pc_type " + pc_type;
  for (const Scope& s : kScopes) {
    const std::string n = s.name;
    if (!(n.back() == '_' ? starts_with(name, s.name) : name == n)) continue;
    switch (s.reader) {
      case Reader::fourier:
        if (!fourier) return in_use;
        break;
      case Reader::band:
        if (!band) return in_use;
        break;
      case Reader::bulk_types:
        if (!fourier && !bulk) return in_use;
        break;
      case Reader::region_types:
        if (bulk) return in_use + ", which re-assembles the whole Jacobian and has no region around the cells";
        if (!fourier && !band)
          return in_use + ", which refreshes its preconditioner every -coupling_pc_lag solves";
        break;
      case Reader::cellfsi_types:
        if (!fourier && !band && !bulk)
          return in_use + ", which refreshes its preconditioner every -coupling_pc_lag solves";
        break;
      case Reader::petsc_pcs:
        if (fourier || band || bulk)
          return in_use + ", which is refreshed by the motion of the cells (-coupling_refresh_steps)";
        break;
    }
  }
  return "";
}

bool read_at_first_solve(const std::string& name) {
  for (const char* p : {"coupling_fourier_region_", "coupling_band_", "coupling_sub_"})
    if (starts_with(name, p)) return true;
  return false;
}

bool option_of_replaced_solver(const std::string& name) {
  for (const char* p :
       {"coupling_band_", "coupling_fourier_", "coupling_pc_", "coupling_sub_", "coupling_mat_"})
    if (starts_with(name, p)) return true;
  return false;
}

std::string region_option_unread(const std::string& name, int dim, bool region_pc_given) {
  // Unless -coupling_fourier_region_pc_type says otherwise, the region's LU is the default of its dimension,
  // which in 3D (cellfsi_lu_single) reads no factorisation options.
  const std::string region_pc = solvers::default_region_pc_type(dim == 3);
  const bool factor_option =
      starts_with(name, "coupling_fourier_region_") &&
      (name.find("mat_mumps_") != std::string::npos || name.find("pc_factor_") != std::string::npos);
  if (region_pc_given || !factor_option || region_pc != solvers::kPCLUSingle) return "";
  return "in " + std::to_string(dim) + "D the region's LU is in single precision (" + region_pc +
         "), which takes no factorisation options; add -coupling_fourier_region_pc_type lu for MUMPS in "
         "double "
         "precision (docs/design.md §8)";
}

}  // namespace cellfsi::coupling
