// A solid solver written outside cellfsi: a rigid disk carried by the flow (a neutrally buoyant tracer that
// translates with the mean fluid velocity at its points). It implements cellfsi::solid::SolidSolver and runs
// through cellfsi's FsiCoupler in the paper's shear box; the disk, off the mid-plane, must move with the
// shear flow there. Exit code 0 when it does (to 1 %), 1 otherwise.
#include <petscsys.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "common/petsc_error.hpp"
#include "coupling/fsi_coupler.hpp"
#include "fluid/fluid_solver.hpp"
#include "geometry/builders.hpp"
#include "solid/solid_solver.hpp"

using namespace cellfsi;
using solid::Mat3;
using solid::Vec3;

class RigidDisk final : public solid::SolidSolver {
 public:
  RigidDisk(double radius, const Vec3& centre, int n_points)
      : reference_(geometry::bulky_ellipse(radius, radius, 2, 16, 2, centre)) {
    for (int i = 0; i < n_points; ++i) {
      const double a = 2 * M_PI * i / n_points;
      rim_.push_back(centre + radius * Vec3(std::cos(a), std::sin(a), 0));
    }
  }
  std::string name() const override { return "disk"; }
  int dim() const override { return 2; }
  void begin_step(const solid::TimeParameters& t) override {
    dt_ = t.dt;
    shift_ = shift_n_ + dt_ * velocity_n_;  // predictor: the same velocity
  }
  std::vector<Vec3> collocation_points() const override { return moved(rim_); }
  double kinematic_update(const std::vector<solid::VelocitySample>& samples) override {
    Vec3 v = Vec3::Zero();
    for (const auto& s : samples) v += s.v;
    v /= static_cast<double>(samples.size());
    // Backward Euler for the translation: (shift - shift_n) / dt = v.
    const double residual = ((shift_ - shift_n_) / dt_ - v).norm();
    shift_ = shift_n_ + dt_ * v;
    velocity_ = v;
    return residual;
  }
  std::vector<solid::QuadratureData> quadrature_data(double, bool) const override { return {}; }  // no stress
  std::vector<Vec3> interface_points() const override { return moved(rim_); }
  void end_step() override { shift_n_ = shift_, velocity_n_ = velocity_; }
  void set_rate(const std::vector<Vec3>& rate) override {
    velocity_n_.setZero();
    for (const Vec3& r : rate) velocity_n_ += r;
    velocity_n_ /= static_cast<double>(rate.size());
  }
  std::vector<double> state() const override {
    return {shift_n_[0], shift_n_[1], velocity_n_[0], velocity_n_[1]};
  }
  void set_state(const std::vector<double>& s) override {
    shift_n_ = shift_ = Vec3(s.at(0), s.at(1), 0);
    velocity_n_ = velocity_ = Vec3(s.at(2), s.at(3), 0);
  }
  bool is_membrane() const override { return false; }
  geometry::Patch reference_patch() const override { return reference_; }
  geometry::Patch current_patch() const override {
    return geometry::transformed(reference_, Mat3::Identity(), shift_n_);
  }
  std::vector<Mat3> cauchy_stress(const std::vector<geometry::Param>& xi) const override {
    return std::vector<Mat3>(xi.size(), Mat3::Zero());
  }
  Vec3 displacement() const { return shift_n_; }

 private:
  std::vector<Vec3> moved(const std::vector<Vec3>& p) const {
    std::vector<Vec3> out;
    for (const Vec3& x : p) out.push_back(x + shift_);
    return out;
  }
  geometry::Patch reference_;
  std::vector<Vec3> rim_;
  double dt_ = 0;
  Vec3 shift_ = Vec3::Zero(), shift_n_ = Vec3::Zero(), velocity_ = Vec3::Zero(), velocity_n_ = Vec3::Zero();
};

int main(int argc, char** argv) {
  if (PetscInitialize(&argc, &argv, nullptr, nullptr) != 0) return 1;
  int status = 1;
  try {
    // The paper's shear box: 0.0024 x 0.0012 cm, periodic in x, walls at -+0.042 cm/s (70 1/s).
    const double L = 0.0024, H = 0.0012, rate = 70.0, dt = 5e-4;
    const geometry::Patch box = geometry::rectangle(L, H, 48, 24, 2, {true, false});
    fluid::FluidOptions fo;
    fo.dt = dt;
    fo.wall_velocity[1][0] = Vec3(-rate * H / 2, 0, 0);
    fo.wall_velocity[1][1] = Vec3(rate * H / 2, 0, 0);
    fluid::FluidSolver fluid(PETSC_COMM_WORLD, box, fo);
    fluid.set_initial_velocity([&](const Vec3& x) { return Vec3(rate * (x[1] - H / 2), 0, 0); });
    fluid.setup();
    // The disk a quarter of the height above the mid-plane, where the flow goes at rate * H / 4.
    RigidDisk disk(1e-4, Vec3(L / 2, 0.75 * H, 0), 32);
    coupling::CouplerOptions co;
    co.s_interface = 1;  // a tracer: the fluid's stabilisation unchanged around it
    coupling::FsiCoupler coupler(fluid, {&disk}, co);
    coupler.initialize();
    const int steps = 10;
    int linear = 0;
    for (int k = 0; k < steps; ++k) {
      const coupling::CouplerStats st = coupler.step();
      if (!st.converged) throw std::runtime_error("step " + std::to_string(k + 1) + ": " + st.reason);
      linear += st.linear_iterations;
    }
    // The tracer leaves the shear flow undisturbed: the fluid's residual stays at round-off, which the linear
    // solver must not chase (it once took 170-490 FGMRES iterations per solve on it).
    if (linear > steps)
      throw std::runtime_error(std::to_string(linear) + " linear iterations in " + std::to_string(steps) +
                               " steps of an undisturbed flow");
    const double expected = rate * H / 4 * steps * dt, moved = disk.displacement()[0];
    PetscPrintf(PETSC_COMM_WORLD, "rigid disk moved %.6e cm in x (the shear flow there: %.6e cm)\n", moved,
                expected);
    status =
        std::abs(moved - expected) <= 0.01 * expected && std::abs(disk.displacement()[1]) < 1e-3 * expected
            ? 0
            : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "rigid_body: %s\n", e.what());
  }
  PetscFinalize();
  return status;
}
