#pragma once
// A fill-reducing ordering for the region's sparse LU: SCOTCH's nested dissection of the matrix's node graph,
// registered with PETSc as the MatOrdering type "cellfsi_nd" (-pc_factor_mat_ordering_type cellfsi_nd).
//
// Why: the region of cellfsi_fourier (solvers/region_corrected.hpp) is a closed shell of 4-6 node layers
// around each cell. Its LU costs what its nested dissection's top fronts cost, and the orderings MUMPS has in
// Debian's build (PORD, AMD, QAMD; no METIS or SCOTCH) leave wider fronts than SCOTCH on this graph.
// Measured on the region of the paper's 64^3 (62 680 unknowns, one rank; docs/design.md §8): PORD 2.08e12
// operations and a 52 s set-up, this ordering 1.61e12 and 42 s; SuperLU_DIST with (Par)METIS 1.5e12.
//
// The graph is that of nodes (rows grouped by the matrix's block size, e.g. 4 unknowns per node of the
// Navier-Stokes box; a BAIJ matrix, which PETSc orders by block rows, by its block rows), so a node's
// unknowns stay together and SCOTCH orders 4 times fewer vertices; the pattern is made symmetric (A + A^T). PETSc hands the ordering to MUMPS only on one rank and for an AIJ
// matrix (MatLUFactorSymbolic_AIJMUMPS with centralized input); RegionCorrectedSolver converts the region to
// AIJ when this ordering is asked for.
#include <petscmat.h>

#include <vector>

namespace cellfsi::solvers {

inline constexpr const char* kMatOrderingNestedDissection = "cellfsi_nd";

/// Registers "cellfsi_nd" with PETSc (once; later calls do nothing). After PetscInitialize.
void register_orderings();

/// The pure part: SCOTCH's nested dissection of an undirected graph given in CSR form (xadj has n + 1
/// entries; adj lists each vertex's neighbours, without itself, every edge in both directions). Returns
/// position[v], the place of vertex v in the elimination order (a permutation of 0..n-1).
std::vector<int> nested_dissection(const std::vector<int>& xadj, const std::vector<int>& adj);

/// The same from neighbour lists (neighbours[v]: v's neighbours, repeats allowed, every edge in both lists;
/// the lists are consumed).
std::vector<int> nested_dissection(std::vector<std::vector<int>> neighbours);

}  // namespace cellfsi::solvers
