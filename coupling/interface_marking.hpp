#pragma once
// s^h marking (docs/design.md §3): the Eulerian basis functions whose support contains an interface point
// of a solid get the control value s_I, all others 1. Rebuilt whenever the solids move.
#include <vector>

#include "coupling/locator.hpp"

namespace cellfsi::coupling {

/// Which Eulerian basis functions "intersect the interface" (paper Sec. 2.2; the paper does not say more).
enum class Marking {
  /// Every function nonzero on an element holding an interface point: s^h > 1 on a band of 2p + 1 elements.
  support,
  /// Only the functions for which that element is an inner element of their support in every direction (for
  /// p >= 2; all of them for p = 1): s^h > 1 on 2p - 1 elements, and still >= s_I / 2^d at the interface
  /// (tested: >= s_I / 4 in 2D with quadratics, >= 0.69 s_I with cubics).
  central,
};

/// Natural (folded) indices of the Eulerian basis functions marked for the points (see Marking), sorted and
/// unique. Points outside the domain are an error (Locator::locate_or_throw).
std::vector<int> functions_near(const Locator& locator, const std::vector<geometry::Vec3>& points,
                                Marking marking = Marking::support);

/// s_I must be at least 1 (it scales the stabilisation up at interfaces); throws std::invalid_argument
/// otherwise. The coupling layer's one check of it (the scene options also refuse values outside their
/// range).
void check_interface_scaling(double s_interface);

/// The scaling field's control values: s_interface on `marked`, 1 elsewhere (size: the patch's control
/// points). s_interface is checked by check_interface_scaling.
std::vector<double> scaling_values(int n_control, const std::vector<int>& marked, double s_interface);

/// The largest s_I the scenes accept: beyond it s_I outweighs the rest of the Jacobian by more than its LU
/// resolves in double precision (1e300 failed the factorisation).
constexpr double kMaxInterfaceScaling = 1e12;

/// Width [cm] of the band where s^h > 1 around an interface: 2p - 1 elements of size `element_size` with
/// the central marking (p >= 2), 2p + 1 with the support marking (and with p = 1).
double interface_band_width(double element_size, int degree, Marking marking);

/// The s_I that keeps a membrane's area error |r_A| (paper Eq. 21) at about `target_area_error` over a run
/// (-s_interface auto): s_I = s_ref (r_ref / target)^2 (w_ref / w)^2.8, w the band's width
/// (interface_band_width). Not clamped to [1, kMaxInterfaceScaling]: the caller says when the target needs
/// more. Fitted on the measured runs of docs/validation.md, "The automatic s_I": r_A ~ s_I^(-1/2), and
/// about 7 = 2^2.8 times more s_I per halving of the band for the same r_A; the constants are the envelope
/// of every measured run whose cell is wider than the band.
double automatic_interface_scaling(double element_size, int degree, Marking marking,
                                   double target_area_error);

}  // namespace cellfsi::coupling
