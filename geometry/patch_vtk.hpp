#pragma once
// Writing patches for ParaView: the patch sampled on a structured grid (.vts) and its element (knot) lines as
// polylines (.vtp); a .pvd collection groups files as parts and/or time steps.
#include <string>
#include <vector>

#include "geometry/patch.hpp"

class vtkXMLWriter;

namespace cellfsi::geometry {

/// Parametric sample values of one direction: every element split into `samples_per_element` equal intervals,
/// the ends included (n_elements * samples_per_element + 1 values).
std::vector<double> sample_values(const KnotVector& kv, int samples_per_element);

/// The parametric points of write_patch_vts's grid, in its order (direction 0 fastest).
std::vector<Param> sample_grid(const Patch& patch, int samples_per_element);

/// Point data given as values at the points of sample_grid (components per point, interleaved).
struct PointField {
  std::string name;
  int components = 1;
  std::vector<double> values;
};

/// Writes the patch sampled with `samples_per_element` intervals per element and direction to `path` (.vts).
/// Point data: "parametric" (xi), for parametric dimension == physical dimension "map_jacobian" (det dx/dxi of the map; the solid output's "J" is the deformation's), and
/// `fields`.
void write_patch_vts(const Patch& patch, const std::string& path, int samples_per_element = 4,
                     const std::vector<PointField>& fields = {});

/// Writes the element boundaries (lines of constant parametric coordinate at every breakpoint), each sampled
/// with `samples_per_element` intervals per element, to `path` (.vtp).
void write_patch_elements_vtp(const Patch& patch, const std::string& path, int samples_per_element = 8);

/// One dataset in a .pvd collection: file name relative to the .pvd, time step and part index.
struct PvdEntry {
  std::string file;
  double time = 0;
  int part = 0;
  std::string name;  // shown by ParaView as the block name when non-empty
};
/// Runs `writer` (its input set) into path atomically: to path + ".tmp", renamed over path once complete.
/// On failure (a missing folder, a full disk, a file-size limit) the temporary file is removed, path is left
/// as it was, and cellfsi::WriteError names path and the system's reason.
void write_vtk_atomically(vtkXMLWriter* writer, const std::string& path);

/// Writes a .pvd collection (atomically: to a temporary file renamed over `path`; WriteError on failure).
void write_pvd(const std::string& path, const std::vector<PvdEntry>& entries);

}  // namespace cellfsi::geometry
