// "arm": a planar arm driven by the policy network, with no physics engine. Fast (tens of
// microseconds per episode) and fully analytic, for tests, smoke experiments and the quick start.
//
// The arm has `joints` links of length 1/joints (reach 1) starting at angle 0 (stretched along +x).
// Observation (joints + 3): joint angles, end-effector x, y, and the episode phase t/steps.
// Action (joints): joint velocities, clipped to [-1, 1]; angle += dt * velocity each step.
// Descriptor "arm-endpoint": the final end-effector position on a bins × bins grid over [-1, 1]².
// Fitness: the negative control effort, or (fitness = "angle-variance") the negative variance of the
// final joint angles, the objective of the planar-arm QD benchmark (Cully et al. 2015; Vassiliades &
// Mouret 2018; the CMA-ME paper's arm).
#pragma once

#include <qd/config.hpp>
#include <qd/descriptor.hpp>
#include <qd/environment.hpp>

namespace qd::arm {

inline constexpr ParamSpec kArmParams[] = {
    param_int("joints", "3", 1, 64, "number of links (each 1/joints long)"),
    param_int("steps", "50", 1, 1000000, "steps per episode"),
    param_float("dt", "0.1", 0.0, kUnbounded, "time step: angle += dt * clipped action"),
    param_int("record_every", "10", 1, 1000000, "trajectory row every N steps (plus the first and the last)"),
    param_string("fitness", "\"effort\"", "effort|angle-variance",
                 "effort = -dt * sum of squared clipped actions; angle-variance = -variance of the final joint "
                 "angles (the planar-arm benchmark's objective)"),
};
inline constexpr ParamSpec kEndpointParams[] = {
    param_int("bins", "50", 1, 10000, "bins per axis over [-1, 1]"),
};

class ArmEnvironment final : public Environment {
 public:
  ArmEnvironment(const Config& cfg, const BuildContext&);
  EnvironmentInfo info() const override;
  void rollout(const RolloutBatch& batch, Trace* traces) const override;
  bool draw_svg(const Trace& trace, std::ostream& out) const override;

  // Forward kinematics of `angles` (joints values) -> end effector.
  void end_effector(const double* angles, double& x, double& y) const;

 private:
  int joints_, steps_, record_every_;
  double dt_;
  bool angle_variance_;
};

class EndpointDescriptor final : public Descriptor {
 public:
  EndpointDescriptor(const Config& cfg, const BuildContext&);
  GridSpec grid() const override;
  void describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const override;
  std::int64_t cell_of(double x, double y) const;

 private:
  int bins_;
};

}  // namespace qd::arm
