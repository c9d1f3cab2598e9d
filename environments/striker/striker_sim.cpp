#include "striker_sim.hpp"

#include <qd/errors.hpp>

#include <box2d/box2d.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace qd::striker {
namespace {

constexpr float kTimeStep = static_cast<float>(1.0 / 25.0);  // the reference passes the double 1/FPS
constexpr int kVelocityIterations = 10;
constexpr int kPositionIterations = 10;
constexpr double kStopSpeed = 0.009;    // _VEL_THRSH
constexpr double kMovedEpsilon = 1e-6;  // _EPS
constexpr double kActionScale[kActionSize] = {10.0, 10.0, 1.0};

constexpr std::uint16_t kCategoryDefault = 0x0001;
constexpr std::uint16_t kCategoryTarget = 0x0010;  // the target and the puck share this category
constexpr std::uint16_t kPuckMaskReference = 0x0001;

// Records puck-wall BeginContacts as wall indices, in the order Box2D reports them.
class WallContactListener final : public b2ContactListener {
 public:
  WallContactListener(const b2Body* puck, const std::array<b2Body*, 4>& walls, std::vector<int>& events)
      : puck_(puck), walls_(walls), events_(events) {}

  void BeginContact(b2Contact* contact) override {
    const b2Body* a = contact->GetFixtureA()->GetBody();
    const b2Body* b = contact->GetFixtureB()->GetBody();
    if (a != puck_ && b != puck_) return;
    // Same order as the reference listener: fixture A's body first, then fixture B's.
    record(a);
    record(b);
  }

 private:
  void record(const b2Body* body) {
    for (int w = 0; w < 4; ++w)
      if (walls_[static_cast<std::size_t>(w)] == body) events_.push_back(w);
  }

  const b2Body* puck_;
  std::array<b2Body*, 4> walls_;
  std::vector<int>& events_;
};

// The table: built exactly in the reference's order (walls S, E, N, W; target; striker; puck),
// since creation order fixes Box2D's proxy and contact order.
struct Scene {
  explicit Scene(const Options& options) : world(b2Vec2(0.0f, 0.0f)) {
    world.SetAllowSleeping(true);

    // Wall polygons as the reference lists them; b2PolygonShape::Set computes the same hull.
    const b2Vec2 horizontal[4] = {{50.0f, 0.0f}, {-50.0f, 0.0f}, {50.0f, 1.0f}, {-50.0f, 1.0f}};
    const b2Vec2 vertical[4] = {{0.0f, 50.0f}, {0.0f, -50.0f}, {1.0f, 50.0f}, {1.0f, -50.0f}};
    const b2Vec2 wall_positions[4] = {{50.0f, 0.0f}, {99.0f, 50.0f}, {50.0f, 99.0f}, {0.0f, 50.0f}};
    for (int i = 0; i < 4; ++i) {
      b2BodyDef def;
      def.type = b2_staticBody;
      def.position = wall_positions[i];
      b2Body* body = world.CreateBody(&def);
      b2PolygonShape shape;
      shape.Set(i % 2 ? vertical : horizontal, 4);
      b2FixtureDef fixture;
      fixture.shape = &shape;
      fixture.density = 5.0f;
      fixture.friction = 0.1f;
      fixture.restitution = 0.0f;
      body->CreateFixture(&fixture);
      walls[static_cast<std::size_t>(i)] = body;
    }

    {
      b2BodyDef def;
      def.type = b2_staticBody;
      def.position.Set(static_cast<float>(kTargetX), static_cast<float>(kTargetY));
      target = world.CreateBody(&def);
      b2CircleShape shape;
      shape.m_radius = static_cast<float>(kTargetRadius);
      b2FixtureDef fixture;
      fixture.shape = &shape;
      fixture.density = 5.0f;
      fixture.friction = 0.1f;
      fixture.filter.categoryBits = kCategoryTarget;
      target->CreateFixture(&fixture);
    }

    {
      // The reference creates the striker at the origin and moves it before any step; creating it
      // at the start pose directly is equivalent (README.md, "Simulation").
      b2BodyDef def;
      def.type = b2_dynamicBody;
      def.position.Set(static_cast<float>(kStrikerStartX), static_cast<float>(kStrikerStartY));
      def.angle = 0.0f;
      def.linearDamping = 0.05f;
      def.angularDamping = 0.5f;
      striker = world.CreateBody(&def);
      const float hx = static_cast<float>(kStrikerHalfWidth), hy = static_cast<float>(kStrikerHalfHeight);
      const b2Vec2 corners[4] = {{-hx, hy}, {hx, hy}, {hx, -hy}, {-hx, -hy}};
      b2PolygonShape shape;
      shape.Set(corners, 4);
      b2FixtureDef fixture;
      fixture.shape = &shape;
      fixture.density = 5.0f;
      fixture.friction = 0.1f;
      fixture.restitution = 0.0f;
      striker->CreateFixture(&fixture);
    }

    {
      b2BodyDef def;
      def.type = b2_dynamicBody;
      def.position.Set(static_cast<float>(kPuckStartX), static_cast<float>(kPuckStartY));
      def.angle = 0.0f;
      def.linearDamping = 0.05f;
      puck = world.CreateBody(&def);
      b2CircleShape shape;
      shape.m_radius = static_cast<float>(kPuckRadius);
      b2FixtureDef fixture;
      fixture.shape = &shape;
      fixture.density = 5.0f;
      fixture.friction = 0.9f;
      fixture.restitution = 0.1f;
      fixture.filter.categoryBits = kCategoryTarget;
      // Reference: mask 0x0001 (walls and striker only), so the puck passes through the target.
      fixture.filter.maskBits = options.puck_hits_target
                                    ? static_cast<std::uint16_t>(kPuckMaskReference | kCategoryTarget)
                                    : kPuckMaskReference;
      puck->CreateFixture(&fixture);
    }
  }

  b2World world;
  std::array<b2Body*, 4> walls{};
  b2Body* target = nullptr;
  b2Body* striker = nullptr;
  b2Body* puck = nullptr;
};

struct Pose {
  double striker_x, striker_y, striker_angle, puck_x, puck_y;
};

Pose read_pose(const Scene& scene) {
  const b2Vec2& s = scene.striker->GetPosition();
  const b2Vec2& p = scene.puck->GetPosition();
  return {normalise_x(s.x), normalise_y(s.y), static_cast<double>(scene.striker->GetAngle()), normalise_x(p.x),
          normalise_y(p.y)};
}

void observe(const Scene& scene, const Pose& pose, const Options& options, Observation& obs) {
  const b2Vec2& sv = scene.striker->GetLinearVelocity();
  const b2Vec2& pv = scene.puck->GetLinearVelocity();
  obs[0] = static_cast<float>(pose.striker_x);
  obs[1] = static_cast<float>(pose.striker_y);
  obs[2] = static_cast<float>(pose.striker_angle);
  obs[3] = static_cast<float>(pose.puck_x);
  obs[4] = static_cast<float>(pose.puck_y);
  obs[5] = sv.x;
  obs[6] = sv.y;
  obs[7] = scene.striker->GetAngularVelocity();
  obs[8] = pv.x;
  obs[9] = pv.y;
  // Normalised distances from the puck centre to the outer wall edges (S, E, N, W).
  obs[10] = static_cast<float>(pose.puck_y + 0.5);
  obs[11] = static_cast<float>(1.0 - pose.puck_x);
  obs[12] = static_cast<float>(1.5 - pose.puck_y);
  obs[13] = static_cast<float>(pose.puck_x + 1.0);
  if (options.mix_scale)
    for (int i : mix_scaled_entries(options.mix_scale_elements)) obs[static_cast<std::size_t>(i)] *= kMixScale;
}

void record_row(const Pose& pose, Trace& trace) {
  trace.main.push(pose.puck_x, pose.puck_y);
  trace.aux.push(pose.striker_x, pose.striker_y, pose.striker_angle);
}

class PolicyController final : public Controller {
 public:
  explicit PolicyController(Policy& policy) : policy_(policy) {}
  const float* act(const float* observation) override { return policy_.act(observation); }

 private:
  Policy& policy_;
};

}  // namespace

const std::array<int, 6>& mix_scaled_entries(MixScaleElements elements) noexcept {
  static constexpr std::array<int, 6> kCompanion = {3, 4, 10, 11, 12, 13};
  static constexpr std::array<int, 6> kPaper = {0, 1, 3, 4, 8, 9};
  return elements == MixScaleElements::kPaper ? kPaper : kCompanion;
}

void run_episode(const Options& options, Controller& controller, Trace& trace, std::vector<Observation>* observations) {
  trace.clear();
  trace.main.reset(2);
  trace.aux.reset(3);
  if (observations) observations->clear();

  Scene scene(options);
  WallContactListener listener(scene.puck, scene.walls, trace.events);
  scene.world.SetContactListener(&listener);

  Pose pose = read_pose(scene);
  Observation obs{};
  observe(scene, pose, options, obs);
  if (observations) observations->push_back(obs);
  record_row(pose, trace);

  for (int step = 0; step < options.max_steps; ++step) {
    const float* raw = controller.act(obs.data());
    if (!std::isfinite(raw[0]) || !std::isfinite(raw[1]) || !std::isfinite(raw[2])) {
      trace.status = EvalStatus::kInvalidAction;
      trace.message = "policy output is not finite at step " + std::to_string(step);
      break;
    }
    const bool policy_active = step < kPolicyActiveSteps;
    double action[kActionSize];
    double action_norm_sq = 0.0;
    for (int j = 0; j < kActionSize; ++j) {
      const float a = policy_active ? std::clamp(raw[j], -1.0f, 1.0f) : 0.0f;
      action[j] = kActionScale[j] * static_cast<double>(a);
      action_norm_sq += action[j] * action[j];
    }
    scene.striker->SetLinearVelocity(b2Vec2(static_cast<float>(action[0]), static_cast<float>(action[1])));
    scene.striker->SetAngularVelocity(static_cast<float>(action[2]));
    scene.world.Step(kTimeStep, kVelocityIterations, kPositionIterations);
    ++trace.steps;

    pose = read_pose(scene);
    if (!std::isfinite(pose.puck_x) || !std::isfinite(pose.puck_y) || !std::isfinite(pose.striker_x) ||
        !std::isfinite(pose.striker_y) || !std::isfinite(pose.striker_angle)) {
      trace.status = EvalStatus::kDiverged;
      trace.message = "non-finite body position after step " + std::to_string(step);
      break;
    }
    observe(scene, pose, options, obs);
    if (observations) observations->push_back(obs);

    const b2Vec2& pv = scene.puck->GetLinearVelocity();
    const double puck_speed =
        std::sqrt(static_cast<double>(pv.x) * static_cast<double>(pv.x) + static_cast<double>(pv.y) * pv.y);
    const double puck_offset = std::sqrt(pose.puck_x * pose.puck_x + pose.puck_y * pose.puck_y);
    const bool done =
        puck_speed <= kStopSpeed && (puck_offset > kMovedEpsilon || std::sqrt(action_norm_sq) <= kStopSpeed);

    if (step % kRowEvery == 0 || done) record_row(pose, trace);
    if (done) break;
  }

  // The listener dies before the world does; make sure nothing can call it in between.
  scene.world.SetContactListener(nullptr);

  // Reference truncation: only the first max_steps / 20 rows are kept (the reset row included).
  const auto max_rows = static_cast<std::size_t>(options.max_steps / kRowEvery);
  trace.main.truncate(max_rows);
  trace.aux.truncate(max_rows);
  trace.fitness = reference_fitness(trace.aux);
}

void run_policy_episode(const Options& options, Policy& policy, const double* theta, Trace& trace,
                        std::vector<Observation>* observations) {
  QD_CHECK(policy.shape().inputs() == kObservationSize && policy.shape().outputs() == kActionSize,
           "striker: the policy must map 14 observations to 3 actions");
  policy.load(theta);
  PolicyController controller(policy);
  run_episode(options, controller, trace, observations);
}

void warm_up_box2d() {
  b2World world(b2Vec2(0.0f, 0.0f));
  b2BodyDef ground_def;
  b2Body* ground = world.CreateBody(&ground_def);
  b2PolygonShape box;
  box.SetAsBox(1.0f, 1.0f);
  ground->CreateFixture(&box, 0.0f);
  b2BodyDef ball_def;
  ball_def.type = b2_dynamicBody;
  ball_def.position.Set(0.5f, 0.5f);  // overlaps the box, so the first step creates a contact
  b2Body* ball = world.CreateBody(&ball_def);
  b2CircleShape circle;
  circle.m_radius = 1.0f;
  ball->CreateFixture(&circle, 1.0f);
  world.Step(kTimeStep, kVelocityIterations, kPositionIterations);
  QD_CHECK(world.GetContactCount() > 0, "striker: Box2D warm-up world made no contact");
}

std::uint16_t to_half_bits(double value) {
  const std::uint16_t sign = std::signbit(value) ? 0x8000u : 0u;
  if (std::isnan(value)) return static_cast<std::uint16_t>(sign | 0x7e00u);
  const double a = std::fabs(value);
  // 65520 is halfway between the largest half (65504) and 2^16: it and above round to infinity.
  if (a >= 65520.0) return static_cast<std::uint16_t>(sign | 0x7c00u);
  if (a < 0x1p-14) {
    // Subnormal (or rounds up to the smallest normal, which the same formula encodes as 0x0400).
    const double units = std::nearbyint(a * 0x1p24);
    return static_cast<std::uint16_t>(sign | static_cast<std::uint16_t>(units));
  }
  const int exponent = std::ilogb(a);                                    // -14 .. 15
  const double mantissa = std::nearbyint(std::ldexp(a, 10 - exponent));  // 1024 .. 2048, ties to even
  // A mantissa of 2048 carries into the exponent, which the addition does by itself.
  const unsigned bits = (static_cast<unsigned>(exponent + 15) << 10) + static_cast<unsigned>(mantissa) - 1024u;
  return static_cast<std::uint16_t>(sign | bits);
}

double reference_fitness(const Series& aux) {
  const std::size_t rows = aux.rows();
  const auto cols = static_cast<std::size_t>(aux.cols);
  std::vector<std::vector<std::uint16_t>> keys(rows, std::vector<std::uint16_t>(cols));
  for (std::size_t r = 0; r < rows; ++r)
    for (std::size_t c = 0; c < cols; ++c) {
      std::uint16_t bits = to_half_bits(aux.at(r, static_cast<int>(c)));
      if (bits == 0x8000u) bits = 0;  // numpy compares values: -0 and +0 are one row
      keys[r][c] = bits;
    }
  std::sort(keys.begin(), keys.end());
  const auto unique = std::unique(keys.begin(), keys.end()) - keys.begin();
  return -static_cast<double>(unique);
}

}  // namespace qd::striker
