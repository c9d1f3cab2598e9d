// The Striker simulation (README.md, "Simulation"): one episode in a fresh Box2D world.
//
// Shared by the plugin (StrikerEnvironment::rollout) and the bare benchmark, so that the two run
// exactly the same code and a throughput comparison measures framework overhead only.
#pragma once

#include <qd/policy.hpp>
#include <qd/types.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace qd::striker {

inline constexpr int kObservationSize = 14;
inline constexpr int kActionSize = 3;
// A trajectory row is kept after every step with step % kRowEvery == 0 (and at done); at most
// max_steps / kRowEvery rows survive (as in the reference; README.md, "Trace layout").
inline constexpr int kRowEvery = 20;
// The reference zeroes the action once its step counter (starting at -1) exceeds 100: the policy
// controls the first 102 calls to step().
inline constexpr int kPolicyActiveSteps = 102;
// Mix-scale multiplies six observation entries by this; which six: MixScaleElements.
inline constexpr float kMixScale = 100.0f;

// World geometry in world units (SCALE 5, 500x500 viewport -> 100x100).
inline constexpr double kWorldSize = 100.0;
inline constexpr double kWallThickness = 1.0;
inline constexpr double kPuckRadius = 2.5;
inline constexpr double kTargetRadius = 10.0;
inline constexpr double kTargetX = 25.0, kTargetY = 75.0;
inline constexpr double kStrikerHalfWidth = 5.0, kStrikerHalfHeight = 2.5;
inline constexpr double kStrikerStartX = 50.0, kStrikerStartY = 10.0;
inline constexpr double kPuckStartX = 50.0, kPuckStartY = 25.0;

// Normalised coordinates used by observations, trajectories and the descriptor.
inline double normalise_x(double world_x) {
  return (world_x - 50.0) / 50.0;
}
inline double normalise_y(double world_y) {
  return (world_y - 25.0) / 50.0;
}
inline double world_x(double x_n) {
  return 50.0 * x_n + 50.0;
}
inline double world_y(double y_n) {
  return 50.0 * y_n + 25.0;
}

// The observation entries that mix-scale multiplies by kMixScale.
enum class MixScaleElements {
  kCompanion,  // obs[3], obs[4], obs[10..13]: puck position and wall distances (the companion code)
  kPaper,      // obs[0], obs[1], obs[3], obs[4], obs[8], obs[9]: the paper's text, the exteroceptive inputs
               // (puck position and velocity) and the striker's absolute position
};

// The six observation indices multiplied by kMixScale under `elements`, in ascending order.
const std::array<int, 6>& mix_scaled_entries(MixScaleElements elements) noexcept;

struct Options {
  bool mix_scale = false;  // multiply the mix_scale_elements entries of the observation by 100
  MixScaleElements mix_scale_elements = MixScaleElements::kCompanion;
  bool puck_hits_target = false;  // false = reference: only the striker collides with the target
  int max_steps = 1000;
};

using Observation = std::array<float, kObservationSize>;

// Whatever turns observations into raw (unclipped) actions. The episode calls act() once per step,
// also after the policy cut-off, as the reference does (its output is then discarded).
class Controller {
 public:
  virtual ~Controller() = default;
  // Returns kActionSize floats valid until the next call.
  virtual const float* act(const float* observation) = 0;
};

// Runs one episode and fills `trace` (cleared first):
//   main rows  = puck (x_n, y_n); aux rows = striker (x_n, y_n, angle);
//   events     = wall index (0 S, 1 E, 2 N, 3 W) per puck-wall BeginContact, in order;
//   steps      = world steps taken; fitness = reference_fitness(aux).
// If `observations` is given it receives every observation handed to the controller, starting
// with the reset state, plus the one after the final step.
void run_episode(const Options& options, Controller& controller, Trace& trace,
                 std::vector<Observation>* observations = nullptr);

// Loads `theta` into `policy` (which must be 14 -> ... -> 3) and runs one episode with it.
void run_policy_episode(const Options& options, Policy& policy, const double* theta, Trace& trace,
                        std::vector<Observation>* observations = nullptr);

// Box2D 2.4.1 initialises its contact-function table lazily and unsynchronised on the first
// contact ever created. Calling this once on the main thread before rollouts run in parallel
// makes that initialisation happen-before every worker.
void warm_up_box2d();

// The reference's unused fitness: -(number of distinct aux rows after rounding to float16).
double reference_fitness(const Series& aux);

// IEEE binary16 bit pattern of `value`, rounded to nearest even (what numpy's astype(float16) does).
std::uint16_t to_half_bits(double value);

}  // namespace qd::striker
