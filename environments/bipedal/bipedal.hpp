// Bipedal Walker and Bipedal Kicker (README.md; gym 0.11 physics on Box2D 2.4.1).
//
// The plugin classes are thin wrappers around run_episode(), which the tests and the bare-loop
// benchmark call directly. See README.md for observation and trace layouts.
#pragma once

#include <qd/config.hpp>
#include <qd/descriptor.hpp>
#include <qd/environment.hpp>
#include <qd/policy.hpp>
#include <qd/types.hpp>

#include <array>
#include <cstdint>
#include <istream>
#include <memory>
#include <ostream>
#include <utility>
#include <vector>

class b2World;
class b2Body;

namespace qd::bipedal {

enum class Task { kWalker, kKicker };

// Which observation entries mix-scale multiplies by 100.
enum class MixScaleElements {
  kCompanion,  // the companion code: walker 14..25 (lidar, hull x, y); kicker 14..29 (lidar,
               // hull x, y, ball x, y, ball vx, vy)
  kPaper,      // the paper's text: walker 24, 25 (hull x, y, the absolute position only); kicker none (the
               // paper's mix-scale Kicker is the unscaled original)
};

struct EpisodeOptions {
  Task task = Task::kWalker;
  bool mix_scale = false;  // x100 on the mix_scale_elements entries of the observation
  MixScaleElements mix_scale_elements = MixScaleElements::kCompanion;
  // Kicker only, excludes mix_scale: hull and ball positions normalised (hull x / 93.333,
  // (hull y - 4) / 3, ball likewise), the paper's "normal" Kicker.
  bool normalised = false;
  int max_steps = 500;
};

// The entries [first, last) that mix-scale multiplies by 100 for `task` and `elements` (empty for
// the paper's Kicker).
std::pair<int, int> mix_scaled_range(Task task, MixScaleElements elements) noexcept;

// The kicker's normalised observation: x / kTerrainFull, (y - kNormalisedYOffset) / kNormalisedYRange.
inline constexpr double kNormalisedYOffset = 4.0;
inline constexpr double kNormalisedYRange = 3.0;

// Why an episode ended; stored as the single entry of Trace::events.
enum class Termination : int {
  kMaxSteps = 0,     // ran max_steps policy steps
  kHullContact = 1,  // walker: the hull touched the ground (gym game_over)
  kLeftEdge = 2,     // walker: hull x < 0
  kRightEdge = 3,    // walker: hull x > 88.667
  kHullStill = 4,    // walker: |v_hull| <= 0.0005
  kBallMoved = 5,    // kicker done_a: ball slow and moved horizontally
  kAllStill = 6,     // kicker done_b: ball slow and hull |v| <= 0.05
  kBallLanded = 7,   // kicker bounce rule: a lofted ball landed
  kFailed = 8,       // status != kOk (NaN action or diverged physics)
};

inline constexpr int kActionSize = 4;
inline constexpr int kWalkerObservationSize = 26;
inline constexpr int kKickerObservationSize = 30;
inline constexpr int kWalkerMainCols = 3;  // hull x, y, angle
inline constexpr int kWalkerAuxCols = 5;   // contact L, contact R, |hipL - hipR|, vx, vy
inline constexpr int kKickerMainCols = 2;  // ball x, y
inline constexpr int kKickerAuxCols = 12;  // hull x, y, angle, contact L, R, |hipL - hipR|, vx, vy, a0..a3
inline constexpr int kDownsample = 20;     // a trajectory row every 20 steps (as the reference)

inline constexpr double kTerrainStep = 14.0 / 30.0;
inline constexpr int kTerrainLength = 200;
inline constexpr double kTerrainHeight = 400.0 / 30.0 / 4.0;
inline constexpr double kTerrainFull = kTerrainStep * kTerrainLength;  // 93.333, walker BD x scale
inline constexpr double kBallStartX = kTerrainStep * 100;              // 46.667
inline constexpr double kWalkerStartX = kTerrainStep * 100;            // 46.667
inline constexpr double kKickerStartX = kTerrainStep * 95;             // 44.333

int observation_size(Task task) noexcept;

// The 200 walker terrain heights of gym's seed-100 terrain (seed_task = 100; terrain.cpp).
const std::array<double, kTerrainLength>& walker_terrain_heights() noexcept;

// One persistent world of the reference's kicker (README.md, "Ghost balls"): gym's reset destroys
// the terrain, hull and legs of the last episode but not its ball, and the reference reuses one
// world per process, so every earlier episode's ball stays in it. A new BallWorld is the world as
// the environment's constructor leaves it: the flat terrain (kept from episode to episode) and
// one ball at the start position, never stepped.
class BallWorld {
 public:
  BallWorld();
  ~BallWorld();
  BallWorld(BallWorld&&) noexcept;
  BallWorld& operator=(BallWorld&&) noexcept;

  std::size_t balls() const noexcept { return balls_.size(); }
  // Every ball's position, angle, velocities and whether it is awake, in creation order (float32,
  // bit for bit); load() rebuilds the world from that. Contacts and the broad-phase are rebuilt,
  // not restored, which is why the core reloads the worlds after each checkpoint too.
  void save(std::ostream& out) const;
  void load(std::istream& in);

  b2World& world() noexcept { return *world_; }
  void add(b2Body* ball) { balls_.push_back(ball); }

 private:
  std::unique_ptr<b2World> world_;
  std::vector<b2Body*> balls_;  // in creation order
};

// Runs one episode of `policy` (parameters already loaded) into `trace` (cleared first). When
// `observations` is given, every observation the policy saw is appended to it (the first one is
// the observation after reset). Thread-safe: every call builds its own b2World, unless `ghosts`
// (kicker only) gives the persistent world to run in: the episode then also meets the balls of
// earlier episodes there, and leaves its own.
void run_episode(const EpisodeOptions& options, Policy& policy, Trace& trace,
                 std::vector<float>* observations = nullptr, BallWorld* ghosts = nullptr);

// Static facts of the scene an episode builds (after construction, before the reset step), for
// the audit tests against the reference sources: body placement, mass properties, filters, joints.
struct BodyFacts {
  double x = 0.0, y = 0.0, angle = 0.0, mass = 0.0, linear_damping = 0.0;
  double density = 0.0, friction = 0.0, restitution = 0.0;
  std::uint16_t category = 0, mask = 0;
  int fixtures = 0;
  bool dynamic = false;
};
struct JointFacts {
  double anchor_a[2] = {0.0, 0.0}, anchor_b[2] = {0.0, 0.0};  // local anchors
  double lower = 0.0, upper = 0.0, reference_angle = 0.0, motor_speed = 0.0, max_motor_torque = 0.0;
  bool motor = false, limit = false;
  int body_a = -1, body_b = -1;  // 0 hull, 1..4 legs[0..3]
};
struct SceneFacts {
  double gravity_y = 0.0;
  bool allow_sleep = false;
  int terrain_bodies = 0;         // static bodies with one edge each
  double terrain_friction = 0.0;  // of every edge (all equal)
  std::uint16_t terrain_category = 0, terrain_mask = 0;
  std::vector<double> terrain_x, terrain_y;  // edge start points, then the last end point (200 points)
  BodyFacts hull, legs[4], ball;             // ball: kicker only (fixtures = 0 otherwise)
  JointFacts joints[4];                      // hip L, knee L, hip R, knee R
  std::vector<int> creation_order;           // dynamic bodies in creation order: 0 hull, 1..4 legs, 5 ball
};
SceneFacts scene_facts(Task task);

// Box2D 2.4.1 initialises its contact registry lazily on the first contact ever made, without a
// lock. Called from the environment constructors (main thread) so workers never race on it.
void warm_up_box2d();

// Descriptor kernels (values: see README). Return the cell or -1.
std::int64_t walker_gait_cell(const Trace& trace, bool corrected_contact_bins, double* values);
std::int64_t kicker_ball_cell(const Trace& trace, double* values);

// int(clip((v - lo) / (hi - lo) * n, 0, n - 1)), the reference binning rule (README.md).
int bin_index(double v, double lo, double hi, int n) noexcept;

constexpr ParamSpec kWalkerParams[] = {
    param_bool("mix_scale", "false", "multiply the mix_scale_elements observation entries by 100 (mix-scale walker)"),
    param_string("mix_scale_elements", "\"companion\"", "companion|paper",
                 "with mix_scale: companion = entries 14..25 (lidar, hull x, y; the companion code); paper = 24, 25 "
                 "(hull x, y: the absolute position, the paper's text)"),
    param_int("max_steps", "500", 1, 1000000, "maximum policy steps per episode; trace keeps max_steps/20 rows"),
};
constexpr ParamSpec kKickerParams[] = {
    param_bool("mix_scale", "false", "multiply the mix_scale_elements observation entries by 100 (mix-scale kicker)"),
    param_string("mix_scale_elements", "\"companion\"", "companion|paper",
                 "with mix_scale: companion = S = 100 on entries 14..29 (lidar, hull pos, ball pos and velocity; the "
                 "companion code); paper = none (the paper's mix-scale Kicker is the unscaled original)"),
    param_bool("normalised", "false",
               "hull and ball positions normalised: x / 93.333, (y - 4) / 3 (entries 24..27; the paper's normal "
               "Kicker); excludes mix_scale"),
    param_int("max_steps", "500", 1, 1000000, "maximum policy steps per episode; trace keeps max_steps/20 rows"),
    param_int("ghost_balls", "0", 0, 65536,
              "the reference's ghost balls, a reference bug kept as an option (README.md): 0 = off; N = N persistent "
              "worlds (the reference's worker processes), episode e of the run in world e mod N, every earlier "
              "episode's ball staying in its world; runs with backend threads"),
};
constexpr ParamSpec kWalkerGaitParams[] = {
    param_string("contact_bins", "\"reference\"", "reference|corrected",
                 "reference: contact fractions binned into 10 bins with stride 5 (the paper's bug, cells collide); "
                 "corrected: 5 bins"),
};

class BipedalEnvironment : public Environment {
 public:
  BipedalEnvironment(Task task, const Config& cfg);
  EnvironmentInfo info() const override;
  void rollout(const RolloutBatch& batch, Trace* traces) const override;
  bool draw_svg(const Trace& trace, std::ostream& out) const override;
  void save(std::ostream& out) const override;
  void load(std::istream& in) override;
  const EpisodeOptions& options() const noexcept { return options_; }

 private:
  EpisodeOptions options_;
  // Kicker with ghost_balls = N: the N persistent worlds. The core runs a world's episodes in
  // order, one call at a time (environment.hpp), so each element is only ever touched by one thread.
  mutable std::vector<BallWorld> ghost_worlds_;
};

class WalkerEnvironment final : public BipedalEnvironment {
 public:
  WalkerEnvironment(const Config& cfg, const BuildContext&) : BipedalEnvironment(Task::kWalker, cfg) {}
};
class KickerEnvironment final : public BipedalEnvironment {
 public:
  KickerEnvironment(const Config& cfg, const BuildContext&) : BipedalEnvironment(Task::kKicker, cfg) {}
};

class WalkerGaitDescriptor final : public Descriptor {
 public:
  WalkerGaitDescriptor(const Config& cfg, const BuildContext& ctx);
  GridSpec grid() const override;
  void describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const override;

 private:
  bool corrected_;
};

class KickerBallDescriptor final : public Descriptor {
 public:
  KickerBallDescriptor(const Config& cfg, const BuildContext& ctx);
  GridSpec grid() const override;
  void describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const override;
};

}  // namespace qd::bipedal
