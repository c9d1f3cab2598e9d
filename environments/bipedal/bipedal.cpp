// Walker and kicker episodes: gym 0.11's BipedalWalker robot on Box2D 2.4.1 (README.md).
#include "bipedal.hpp"

#include <qd/errors.hpp>

#include <box2d/box2d.h>

#include <qd/state_io.hpp>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>

namespace qd::bipedal {
namespace {

constexpr float kTimeStep = 1.0f / 50.0f;
constexpr double kFps = 50.0;
constexpr int kVelocityIterations = 6 * 30;
constexpr int kPositionIterations = 2 * 30;
constexpr double kScale = 30.0;
constexpr float kMotorsTorque = 80.0f;
constexpr float kSpeedHip = 4.0f;
constexpr float kSpeedKnee = 6.0f;
constexpr double kLidarRange = 160.0 / kScale;
constexpr double kLegDown = -8.0 / kScale;
constexpr double kLegW = 8.0 / kScale;
constexpr double kLegH = 34.0 / kScale;
constexpr double kViewportW = 600.0;
constexpr double kViewportH = 400.0;
constexpr int kTerrainGrass = 10;
constexpr double kRightLimit = (kTerrainLength - kTerrainGrass) * kTerrainStep;  // 88.667
constexpr float kWalkerFriction = 2.5f;
constexpr float kKickerFriction = 0.9f;
constexpr double kInitialPush = 2.3627539207;  // U(-5, 5) of gym's seeding for seed_task = 100
constexpr double kBallRadius = 10.0 / kScale;
constexpr double kMixScale = 100.0;
constexpr int kKickerActiveSteps = 100;  // the action is zeroed once the counter exceeds this
constexpr int kLidarRays = 10;

// Collision filters (as in the reference). Ground is category 1 with the default mask everywhere.
constexpr std::uint16_t kGroundCategory = 0x0001;
constexpr std::uint16_t kWalkerBodyCategory = 0x0020, kWalkerBodyMask = 0x0001;
constexpr std::uint16_t kKickerBodyCategory = 0x0002, kKickerBodyMask = 0x0005;
constexpr std::uint16_t kBallCategory = 0x0004, kBallMask = 0x0003;

// pybox2d (Box2D 2.3) motor setters wake both bodies unconditionally, which only restarts bodies
// that are asleep. 2.4.1's setters instead wake (and reset the sleep timer of) both bodies whenever
// the value changes, so a robot whose action jitters would never fall asleep and the walker's
// |v| <= 0.0005 rule would not fire as in the reference. Writing the members directly and waking
// sleeping bodies ourselves reproduces 2.3. The pointer-to-member through a derived class is the
// standard-conforming way to reach protected members.
struct MotorAccess : b2RevoluteJoint {
  static void set(b2RevoluteJoint* joint, float speed, float torque) {
    joint->*(&MotorAccess::m_motorSpeed) = speed;
    joint->*(&MotorAccess::m_maxMotorTorque) = torque;
  }
};

void wake_if_asleep(b2Body* body) {
  if (!body->IsAwake()) body->SetAwake(true);
}

class ContactFlags final : public b2ContactListener {
 public:
  b2Body* hull = nullptr;
  b2Body* legs[4] = {nullptr, nullptr, nullptr, nullptr};
  b2Body* ball = nullptr;  // kicker only

  bool game_over = false;
  bool ground_contact[2] = {false, false};  // lower legs legs[1], legs[3]
  bool ball_landed = false;
  bool ball_kicked = false;
  bool ball_flying = false;
  bool kick_start = true;

  void BeginContact(b2Contact* contact) override { update(contact, true); }
  void EndContact(b2Contact* contact) override { update(contact, false); }

 private:
  bool is_biped(const b2Body* b) const {
    return b == hull || b == legs[0] || b == legs[1] || b == legs[2] || b == legs[3];
  }

  void update(b2Contact* contact, bool begin) {
    b2Body* a = contact->GetFixtureA()->GetBody();
    b2Body* b = contact->GetFixtureB()->GetBody();
    if (begin && (a == hull || b == hull)) game_over = true;
    if (a == legs[1] || b == legs[1]) ground_contact[0] = begin;
    if (a == legs[3] || b == legs[3]) ground_contact[1] = begin;
    if (ball != nullptr && (a == ball || b == ball)) {
      const b2Body* other = a == ball ? b : a;
      if (other->GetType() == b2_staticBody) {
        ball_landed = begin;
      } else if (is_biped(other)) {
        if (begin) {
          kick_start = false;
          ball_flying = false;
        } else {
          ball_kicked = true;
        }
      }
    }
  }
};

// Closest ground hit; other categories are ignored (returning -1 skips the fixture).
class LidarRay final : public b2RayCastCallback {
 public:
  float fraction = 1.0f;
  float ReportFixture(b2Fixture* fixture, const b2Vec2&, const b2Vec2&, float hit_fraction) override {
    if ((fixture->GetFilterData().categoryBits & 1) == 0) return -1.0f;
    fraction = hit_fraction;
    return hit_fraction;
  }
};

struct LidarDirections {
  double dx[kLidarRays];
  double dy[kLidarRays];
  LidarDirections() {
    for (int i = 0; i < kLidarRays; ++i) {
      dx[i] = std::sin(1.5 * i / 10.0) * kLidarRange;
      dy[i] = -std::cos(1.5 * i / 10.0) * kLidarRange;
    }
  }
};
const LidarDirections& lidar_directions() {
  static const LidarDirections directions;
  return directions;
}

void add_terrain(b2World& world, const double* heights, float friction) {
  b2BodyDef body_def;  // static at the origin; the edge carries world coordinates
  b2EdgeShape edge;
  b2FixtureDef fixture;
  fixture.shape = &edge;
  fixture.friction = friction;
  fixture.filter.categoryBits = kGroundCategory;
  for (int i = 0; i + 1 < kTerrainLength; ++i) {
    edge.SetTwoSided(b2Vec2(static_cast<float>(i * kTerrainStep), static_cast<float>(heights[i])),
                     b2Vec2(static_cast<float>((i + 1) * kTerrainStep), static_cast<float>(heights[i + 1])));
    world.CreateBody(&body_def)->CreateFixture(&fixture);
  }
}

const double* flat_heights() {
  static const std::array<double, kTerrainLength> heights = [] {
    std::array<double, kTerrainLength> h{};
    h.fill(kTerrainHeight);
    return h;
  }();
  return heights.data();
}

b2Vec2 gravity() {
  return b2Vec2(0.0f, -10.0f);
}

// The kicker's ball: at its start position (resting 1/3 above the ground), or as `def` says.
b2Body* add_ball(b2World& world, b2BodyDef def) {
  def.type = b2_dynamicBody;
  def.linearDamping = 1.0f;
  b2Body* ball = world.CreateBody(&def);
  b2CircleShape circle;
  circle.m_radius = static_cast<float>(kBallRadius);
  b2FixtureDef fixture;
  fixture.shape = &circle;
  fixture.density = 0.5f;
  fixture.friction = 0.1f;
  fixture.restitution = 0.7f;
  fixture.filter.categoryBits = kBallCategory;
  fixture.filter.maskBits = kBallMask;
  ball->CreateFixture(&fixture);
  return ball;
}
b2BodyDef ball_at_start() {
  b2BodyDef def;
  def.position.Set(static_cast<float>(kBallStartX), static_cast<float>(kTerrainHeight + 2 * kBallRadius));
  return def;
}

class Scene {
 public:
  // A fresh world, or the persistent world `ghosts` (its earlier balls stay; this episode's ball
  // joins them when the scene ends).
  explicit Scene(const EpisodeOptions& options, BallWorld* ghosts = nullptr)
      : task_(options.task),
        own_world_(ghosts ? std::nullopt : std::optional<b2World>(std::in_place, gravity())),
        world_(ghosts ? ghosts->world() : *own_world_),
        ghosts_(ghosts) {
    const bool walker = task_ == Task::kWalker;
    world_.SetContactListener(&contacts_);
    if (ghosts == nullptr)  // a persistent world keeps its terrain (BallWorld)
      add_terrain(world_, walker ? walker_terrain_heights().data() : flat_heights(),
                  walker ? kWalkerFriction : kKickerFriction);
    const std::uint16_t category = walker ? kWalkerBodyCategory : kKickerBodyCategory;
    const std::uint16_t mask = walker ? kWalkerBodyMask : kKickerBodyMask;
    const double init_x = walker ? kWalkerStartX : kKickerStartX;
    const double init_y = kTerrainHeight + 2 * kLegH;

    b2BodyDef hull_def;
    hull_def.type = b2_dynamicBody;
    hull_def.position.Set(static_cast<float>(init_x), static_cast<float>(init_y));
    hull_ = world_.CreateBody(&hull_def);
    const double hull_poly[5][2] = {{-30, 9}, {6, 9}, {34, 1}, {34, -8}, {-30, -8}};
    b2Vec2 vertices[5];
    for (int k = 0; k < 5; ++k)
      vertices[k].Set(static_cast<float>(hull_poly[k][0] / kScale), static_cast<float>(hull_poly[k][1] / kScale));
    b2PolygonShape hull_shape;
    hull_shape.Set(vertices, 5);
    b2FixtureDef hull_fixture;
    hull_fixture.shape = &hull_shape;
    hull_fixture.density = 5.0f;
    hull_fixture.friction = 0.1f;
    hull_fixture.restitution = 0.0f;
    hull_fixture.filter.categoryBits = category;
    hull_fixture.filter.maskBits = mask;
    hull_->CreateFixture(&hull_fixture);
    if (walker) hull_->ApplyForceToCenter(b2Vec2(static_cast<float>(kInitialPush), 0.0f), true);

    b2PolygonShape upper_shape, lower_shape;
    upper_shape.SetAsBox(static_cast<float>(kLegW / 2), static_cast<float>(kLegH / 2));
    lower_shape.SetAsBox(static_cast<float>(0.8 * kLegW / 2), static_cast<float>(kLegH / 2));
    b2FixtureDef leg_fixture;  // friction stays at the default 0.2
    leg_fixture.density = 1.0f;
    leg_fixture.restitution = 0.0f;
    leg_fixture.filter.categoryBits = category;
    leg_fixture.filter.maskBits = mask;

    for (int side = 0; side < 2; ++side) {
      const int i = side == 0 ? -1 : 1;
      b2BodyDef leg_def;
      leg_def.type = b2_dynamicBody;
      leg_def.angle = static_cast<float>(i * 0.05);
      leg_def.position.Set(static_cast<float>(init_x), static_cast<float>(init_y - kLegH / 2 - kLegDown));
      b2Body* upper = world_.CreateBody(&leg_def);
      leg_fixture.shape = &upper_shape;
      upper->CreateFixture(&leg_fixture);

      b2RevoluteJointDef hip;  // filled field by field like gym (reference angle 0, no Initialize)
      hip.bodyA = hull_;
      hip.bodyB = upper;
      hip.localAnchorA.Set(0.0f, static_cast<float>(kLegDown));
      hip.localAnchorB.Set(0.0f, static_cast<float>(kLegH / 2));
      hip.enableMotor = true;
      hip.enableLimit = true;
      hip.maxMotorTorque = kMotorsTorque;
      hip.motorSpeed = static_cast<float>(i);
      hip.lowerAngle = -0.8f;
      hip.upperAngle = 1.1f;
      joints_[2 * side] = static_cast<b2RevoluteJoint*>(world_.CreateJoint(&hip));

      leg_def.position.Set(static_cast<float>(init_x), static_cast<float>(init_y - kLegH * 3 / 2 - kLegDown));
      b2Body* lower = world_.CreateBody(&leg_def);
      leg_fixture.shape = &lower_shape;
      lower->CreateFixture(&leg_fixture);

      b2RevoluteJointDef knee;
      knee.bodyA = upper;
      knee.bodyB = lower;
      knee.localAnchorA.Set(0.0f, static_cast<float>(-kLegH / 2));
      knee.localAnchorB.Set(0.0f, static_cast<float>(kLegH / 2));
      knee.enableMotor = true;
      knee.enableLimit = true;
      knee.maxMotorTorque = kMotorsTorque;
      knee.motorSpeed = 1.0f;
      knee.lowerAngle = -1.6f;
      knee.upperAngle = -0.1f;
      joints_[2 * side + 1] = static_cast<b2RevoluteJoint*>(world_.CreateJoint(&knee));

      legs_[2 * side] = upper;
      legs_[2 * side + 1] = lower;
    }

    if (!walker) ball_ = add_ball(world_, ball_at_start());

    contacts_.hull = hull_;
    for (int k = 0; k < 4; ++k) contacts_.legs[k] = legs_[k];
    contacts_.ball = ball_;
  }

  // In a persistent world, gym's _destroy() at the next reset: the listener goes, then the hull and
  // legs (with their joints); every ball stays. gym destroys and rebuilds the terrain too, which
  // wakes every ball resting on it (destroying a touching contact wakes both bodies) for another
  // half second of simulated settling; the flat terrain is rebuilt where it was, so we keep it
  // instead: the same ground, without re-simulating every resting ball each episode (README.md).
  ~Scene() {
    if (ghosts_ == nullptr) return;
    world_.SetContactListener(nullptr);
    std::vector<b2Body*> doomed;
    for (b2Body* b = world_.GetBodyList(); b != nullptr; b = b->GetNext())
      if (b->GetType() == b2_dynamicBody && b->GetFixtureList()->GetFilterData().categoryBits != kBallCategory)
        doomed.push_back(b);
    for (b2Body* b : doomed) world_.DestroyBody(b);
    ghosts_->add(ball_);
  }
  Scene(const Scene&) = delete;
  Scene& operator=(const Scene&) = delete;

  // gym's step(): motors from the action (kicker: zeroed after the first 101 policy calls), one
  // world step, lidar. `action` is overwritten with the action actually applied.
  void step(float* action) {
    if (task_ == Task::kKicker) {
      if (counter_ > kKickerActiveSteps) std::fill(action, action + kActionSize, 0.0f);
      ++counter_;
    }
    for (int j = 0; j < kActionSize; ++j) {
      const float a = action[j];
      const float sign = a > 0.0f ? 1.0f : (a < 0.0f ? -1.0f : 0.0f);
      const float speed = ((j % 2) == 0 ? kSpeedHip : kSpeedKnee) * sign;
      const float torque = kMotorsTorque * std::min(std::fabs(a), 1.0f);
      wake_if_asleep(joints_[j]->GetBodyA());
      wake_if_asleep(joints_[j]->GetBodyB());
      MotorAccess::set(joints_[j], speed, torque);
    }
    world_.Step(kTimeStep, kVelocityIterations, kPositionIterations);

    const b2Vec2 pos = hull_->GetPosition();
    const LidarDirections& dir = lidar_directions();
    for (int i = 0; i < kLidarRays; ++i) {
      LidarRay ray;
      const b2Vec2 p2(static_cast<float>(pos.x + dir.dx[i]), static_cast<float>(pos.y + dir.dy[i]));
      world_.RayCast(&ray, pos, p2);
      lidar_[i] = ray.fraction;
    }
  }

  // Writes the observation; returns false when it is not finite.
  bool observe(const EpisodeOptions& options, double* obs) const {
    const b2Vec2 vel = hull_->GetLinearVelocity();
    const b2Vec2 pos = hull_->GetPosition();
    obs[0] = hull_->GetAngle();
    obs[1] = 2.0 * hull_->GetAngularVelocity() / kFps;
    obs[2] = 0.3 * vel.x * (kViewportW / kScale) / kFps;
    obs[3] = 0.3 * vel.y * (kViewportH / kScale) / kFps;
    obs[4] = joints_[0]->GetJointAngle();
    obs[5] = joints_[0]->GetJointSpeed() / kSpeedHip;
    obs[6] = joints_[1]->GetJointAngle() + 1.0;
    obs[7] = joints_[1]->GetJointSpeed() / kSpeedKnee;
    obs[8] = contacts_.ground_contact[0] ? 1.0 : 0.0;
    obs[9] = joints_[2]->GetJointAngle();
    obs[10] = joints_[2]->GetJointSpeed() / kSpeedHip;
    obs[11] = joints_[3]->GetJointAngle() + 1.0;
    obs[12] = joints_[3]->GetJointSpeed() / kSpeedKnee;
    obs[13] = contacts_.ground_contact[1] ? 1.0 : 0.0;
    for (int i = 0; i < kLidarRays; ++i) obs[14 + i] = lidar_[i];
    obs[24] = pos.x;
    obs[25] = pos.y;
    int n = kWalkerObservationSize;
    if (ball_ != nullptr) {
      const b2Vec2 bp = ball_->GetPosition();
      const b2Vec2 bv = ball_->GetLinearVelocity();
      obs[26] = bp.x;
      obs[27] = bp.y;
      obs[28] = bv.x;
      obs[29] = bv.y;
      n = kKickerObservationSize;
    }
    if (options.normalised) {
      for (int i : {24, 26}) obs[i] /= kTerrainFull;
      for (int i : {25, 27}) obs[i] = (obs[i] - kNormalisedYOffset) / kNormalisedYRange;
    } else if (options.mix_scale) {
      const auto [first, last] = mix_scaled_range(task_, options.mix_scale_elements);
      for (int i = first; i < last; ++i) obs[i] *= kMixScale;
    }
    for (int i = 0; i < n; ++i)
      if (!std::isfinite(obs[i])) return false;
    return true;
  }

  Termination walker_done() const {
    const b2Vec2 pos = hull_->GetPosition();
    if (contacts_.game_over) return Termination::kHullContact;
    if (pos.x < 0.0) return Termination::kLeftEdge;
    if (pos.x > kRightLimit) return Termination::kRightEdge;
    const b2Vec2 v = hull_->GetLinearVelocity();
    if (std::hypot(static_cast<double>(v.x), static_cast<double>(v.y)) <= 0.0005) return Termination::kHullStill;
    return Termination::kMaxSteps;
  }

  // The kicker discards gym's done and recomputes it (README.md).
  Termination kicker_done() {
    const b2Vec2 bp = ball_->GetPosition();
    const b2Vec2 bv = ball_->GetLinearVelocity();
    const b2Vec2 hv = hull_->GetLinearVelocity();
    const bool ball_slow = std::fabs(static_cast<double>(bv.x)) <= 0.25;
    if (contacts_.ball_kicked && bv.y > 0.1 && !contacts_.ball_landed) contacts_.ball_flying = true;
    if (ball_slow && std::fabs(std::fabs(static_cast<double>(bp.x)) - kBallStartX) > 1e-5)
      return Termination::kBallMoved;
    if (ball_slow && std::hypot(static_cast<double>(hv.x), static_cast<double>(hv.y)) <= 0.05)
      return Termination::kAllStill;
    if (contacts_.ball_flying && contacts_.ball_landed) return Termination::kBallLanded;
    return Termination::kMaxSteps;
  }

  // Walker gym reward for the last step (fitness only; unused by the algorithms).
  double walker_reward(const float* action, double angle) {
    const double shaping = 130.0 * hull_->GetPosition().x / kScale - 5.0 * std::fabs(angle);
    double reward = has_shaping_ ? shaping - prev_shaping_ : 0.0;
    prev_shaping_ = shaping;
    has_shaping_ = true;
    for (int j = 0; j < kActionSize; ++j)
      reward -= 0.00035 * kMotorsTorque * std::min(std::fabs(static_cast<double>(action[j])), 1.0);
    if (contacts_.game_over || hull_->GetPosition().x < 0.0) reward = -100.0;
    return reward;
  }

  SceneFacts facts() const {
    SceneFacts f;
    f.gravity_y = world_.GetGravity().y;
    f.allow_sleep = world_.GetAllowSleeping();
    auto body = [](const b2Body* b, BodyFacts& out) {
      out.x = b->GetPosition().x;
      out.y = b->GetPosition().y;
      out.angle = b->GetAngle();
      out.mass = b->GetMass();
      out.linear_damping = b->GetLinearDamping();
      out.dynamic = b->GetType() == b2_dynamicBody;
      for (const b2Fixture* fx = b->GetFixtureList(); fx != nullptr; fx = fx->GetNext()) {
        ++out.fixtures;
        out.density = fx->GetDensity();
        out.friction = fx->GetFriction();
        out.restitution = fx->GetRestitution();
        out.category = fx->GetFilterData().categoryBits;
        out.mask = fx->GetFilterData().maskBits;
      }
    };
    body(hull_, f.hull);
    for (int k = 0; k < 4; ++k) body(legs_[k], f.legs[k]);
    if (ball_ != nullptr) body(ball_, f.ball);
    const b2Body* index[5] = {hull_, legs_[0], legs_[1], legs_[2], legs_[3]};
    auto which = [&](const b2Body* b) {
      for (int k = 0; k < 5; ++k)
        if (index[k] == b) return k;
      return -1;
    };
    for (int j = 0; j < 4; ++j) {
      b2RevoluteJoint* joint = joints_[j];  // GetBodyA() is not const in Box2D 2.4.1
      JointFacts& out = f.joints[j];
      out.anchor_a[0] = joint->GetLocalAnchorA().x;
      out.anchor_a[1] = joint->GetLocalAnchorA().y;
      out.anchor_b[0] = joint->GetLocalAnchorB().x;
      out.anchor_b[1] = joint->GetLocalAnchorB().y;
      out.lower = joint->GetLowerLimit();
      out.upper = joint->GetUpperLimit();
      out.reference_angle = joint->GetReferenceAngle();
      out.motor_speed = joint->GetMotorSpeed();
      out.max_motor_torque = joint->GetMaxMotorTorque();
      out.motor = joint->IsMotorEnabled();
      out.limit = joint->IsLimitEnabled();
      out.body_a = which(joint->GetBodyA());
      out.body_b = which(joint->GetBodyB());
    }
    // Box2D prepends new bodies to the world's list, so the list runs newest first.
    std::vector<const b2Body*> bodies;
    for (const b2Body* b = world_.GetBodyList(); b != nullptr; b = b->GetNext()) bodies.push_back(b);
    for (auto it = bodies.rbegin(); it != bodies.rend(); ++it) {
      const b2Body* b = *it;
      if (b->GetType() == b2_dynamicBody) {
        f.creation_order.push_back(b == ball_ ? 5 : which(b));
        continue;
      }
      const b2Fixture* fx = b->GetFixtureList();
      const b2EdgeShape* edge = static_cast<const b2EdgeShape*>(fx->GetShape());
      ++f.terrain_bodies;
      f.terrain_friction = fx->GetFriction();
      f.terrain_category = fx->GetFilterData().categoryBits;
      f.terrain_mask = fx->GetFilterData().maskBits;
      f.terrain_x.push_back(edge->m_vertex1.x);
      f.terrain_y.push_back(edge->m_vertex1.y);
      if (f.terrain_bodies == kTerrainLength - 1) {
        f.terrain_x.push_back(edge->m_vertex2.x);
        f.terrain_y.push_back(edge->m_vertex2.y);
      }
    }
    return f;
  }

  void record(Trace& trace, const float* action) const {
    const b2Vec2 pos = hull_->GetPosition();
    const b2Vec2 vel = hull_->GetLinearVelocity();
    const double hip_gap = std::fabs(static_cast<double>(joints_[0]->GetJointAngle()) - joints_[2]->GetJointAngle());
    const double contact_l = contacts_.ground_contact[0] ? 1.0 : 0.0;
    const double contact_r = contacts_.ground_contact[1] ? 1.0 : 0.0;
    if (task_ == Task::kWalker) {
      trace.main.push(pos.x, pos.y, hull_->GetAngle());
      trace.aux.push(contact_l, contact_r, hip_gap, vel.x, vel.y);
    } else {
      const b2Vec2 bp = ball_->GetPosition();
      trace.main.push(bp.x, bp.y);
      trace.aux.push(pos.x, pos.y, hull_->GetAngle(), contact_l, contact_r, hip_gap, vel.x, vel.y, action[0], action[1],
                     action[2], action[3]);
    }
  }

 private:
  Task task_;
  ContactFlags contacts_;  // declared first so that it outlives the world that calls it
  std::optional<b2World> own_world_;
  b2World& world_;
  BallWorld* ghosts_;
  b2Body* hull_ = nullptr;
  b2Body* legs_[4] = {nullptr, nullptr, nullptr, nullptr};
  b2RevoluteJoint* joints_[4] = {nullptr, nullptr, nullptr, nullptr};
  b2Body* ball_ = nullptr;
  float lidar_[kLidarRays] = {};
  int counter_ = -1;  // kicker action counter; the reset step moves it to 0
  bool has_shaping_ = false;
  double prev_shaping_ = 0.0;
};

}  // namespace

int observation_size(Task task) noexcept {
  return task == Task::kWalker ? kWalkerObservationSize : kKickerObservationSize;
}

std::pair<int, int> mix_scaled_range(Task task, MixScaleElements elements) noexcept {
  if (elements == MixScaleElements::kPaper) return task == Task::kWalker ? std::pair{24, 26} : std::pair{0, 0};
  return {14, observation_size(task)};
}

void warm_up_box2d() {
  static std::once_flag once;
  std::call_once(once, [] {
    b2World world(b2Vec2(0.0f, -10.0f));
    b2BodyDef ground_def;
    b2Body* ground = world.CreateBody(&ground_def);
    b2EdgeShape edge;
    edge.SetTwoSided(b2Vec2(-5.0f, 0.0f), b2Vec2(5.0f, 0.0f));
    ground->CreateFixture(&edge, 0.0f);
    b2BodyDef ball_def;
    ball_def.type = b2_dynamicBody;
    ball_def.position.Set(0.0f, 0.1f);
    b2CircleShape circle;
    circle.m_radius = 0.5f;
    world.CreateBody(&ball_def)->CreateFixture(&circle, 1.0f);
    world.Step(kTimeStep, 8, 3);
  });
}

SceneFacts scene_facts(Task task) {
  EpisodeOptions options;
  options.task = task;
  const Scene scene(options);
  return scene.facts();
}

void run_episode(const EpisodeOptions& options, Policy& policy, Trace& trace, std::vector<float>* observations,
                 BallWorld* ghosts) {
  const bool walker = options.task == Task::kWalker;
  if (walker && ghosts != nullptr) throw std::invalid_argument("bipedal: the walker has no ball to leave behind");
  const int n_obs = observation_size(options.task);
  trace.clear();
  trace.main.reset(walker ? kWalkerMainCols : kKickerMainCols);
  trace.aux.reset(walker ? kWalkerAuxCols : kKickerAuxCols);
  const std::size_t max_rows = static_cast<std::size_t>(options.max_steps / kDownsample);
  trace.main.data.reserve((max_rows + 2) * static_cast<std::size_t>(trace.main.cols));
  trace.aux.data.reserve((max_rows + 2) * static_cast<std::size_t>(trace.aux.cols));

  Scene scene(options, ghosts);
  double obs[kKickerObservationSize] = {};
  float obs_f[kKickerObservationSize] = {};
  float action[kActionSize] = {0.0f, 0.0f, 0.0f, 0.0f};
  Termination why = Termination::kMaxSteps;

  auto fail = [&](EvalStatus status, const char* message) {
    trace.status = status;
    trace.message = message;
    why = Termination::kFailed;
  };

  // Reset: one world step with zero action; the first observation and trajectory row follow it.
  scene.step(action);
  if (!scene.observe(options, obs)) {
    fail(EvalStatus::kDiverged, "non-finite state after reset");
  } else {
    if (walker) scene.walker_reward(action, obs[0]);  // sets gym's prev_shaping; this reward is discarded
    scene.record(trace, action);
    for (int step = 0; step < options.max_steps; ++step) {
      for (int i = 0; i < n_obs; ++i) obs_f[i] = static_cast<float>(obs[i]);
      if (observations != nullptr) observations->insert(observations->end(), obs_f, obs_f + n_obs);
      const float* out = policy.act(obs_f);
      for (int j = 0; j < kActionSize; ++j) action[j] = out[j];
      if (!std::all_of(action, action + kActionSize, [](float a) { return std::isfinite(a); })) {
        fail(EvalStatus::kInvalidAction, "policy produced a non-finite action");
        break;
      }
      scene.step(action);
      trace.steps = step + 1;
      if (!scene.observe(options, obs)) {
        fail(EvalStatus::kDiverged, "non-finite state");
        break;
      }
      if (walker) {
        trace.fitness += scene.walker_reward(action, obs[0]);
        why = scene.walker_done();
      } else {
        why = scene.kicker_done();
      }
      const bool done = why != Termination::kMaxSteps;
      if (step % kDownsample == 0 || done) scene.record(trace, action);
      if (done) break;
    }
  }
  // Reference quirk kept: rows after the first max_steps/20 are dropped (the final position used by
  // the descriptors is the state after step min(k_done, 460) for 500 steps).
  trace.main.truncate(max_rows);
  trace.aux.truncate(max_rows);
  trace.events.push_back(static_cast<int>(why));
}

BallWorld::BallWorld() : world_(std::make_unique<b2World>(gravity())) {
  add_terrain(*world_, flat_heights(), kKickerFriction);
  balls_.push_back(add_ball(*world_, ball_at_start()));
}
BallWorld::~BallWorld() = default;
BallWorld::BallWorld(BallWorld&&) noexcept = default;
BallWorld& BallWorld::operator=(BallWorld&&) noexcept = default;

namespace {
constexpr std::uint32_t kBallWorldTag = 0x47424c31;  // "GBL1"
}  // namespace

void BallWorld::save(std::ostream& out) const {
  state::write<std::uint32_t>(out, kBallWorldTag);
  state::write<std::uint64_t>(out, balls_.size());
  for (const b2Body* b : balls_) {
    const b2Vec2 p = b->GetPosition(), v = b->GetLinearVelocity();
    for (float f : {p.x, p.y, b->GetAngle(), v.x, v.y, b->GetAngularVelocity()}) state::write<float>(out, f);
    state::write<std::uint8_t>(out, b->IsAwake() ? 1 : 0);
  }
}

void BallWorld::load(std::istream& in) {
  if (state::read<std::uint32_t>(in) != kBallWorldTag) throw StateError("not a ghost-ball world");
  const auto n = state::read<std::uint64_t>(in);
  if (n == 0 || n > (std::uint64_t{1} << 32)) throw StateError("implausible ghost-ball count " + std::to_string(n));
  auto world = std::make_unique<b2World>(gravity());
  add_terrain(*world, flat_heights(), kKickerFriction);
  std::vector<b2Body*> balls;
  // A count beyond the stream's balls fails on reading them, not on an allocation sized by it.
  balls.reserve(static_cast<std::size_t>(std::min<std::uint64_t>(n, std::uint64_t{1} << 20)));
  for (std::uint64_t k = 0; k < n; ++k) {
    float f[6];
    for (float& x : f) x = state::read<float>(in);
    const bool awake = state::read<std::uint8_t>(in) != 0;
    if (!std::all_of(f, f + 6, [](float x) { return std::isfinite(x); }))
      throw StateError("ghost ball " + std::to_string(k) + " has a non-finite state");
    b2BodyDef def;
    def.position.Set(f[0], f[1]);
    def.angle = f[2];
    def.linearVelocity.Set(f[3], f[4]);
    def.angularVelocity = f[5];
    def.awake = awake;
    balls.push_back(add_ball(*world, def));
  }
  world_ = std::move(world);
  balls_ = std::move(balls);
}

BipedalEnvironment::BipedalEnvironment(Task task, const Config& cfg) {
  options_.task = task;
  options_.mix_scale = cfg.get_bool("mix_scale");
  // The core has already rejected any value outside the declared choices.
  options_.mix_scale_elements =
      cfg.get_string("mix_scale_elements") == "paper" ? MixScaleElements::kPaper : MixScaleElements::kCompanion;
  options_.normalised = cfg.has("normalised") && cfg.get_bool("normalised");
  if (options_.normalised && options_.mix_scale)
    throw ConfigError("normalised", "normalised and mix_scale are two different observations: set at most one");
  options_.max_steps = static_cast<int>(cfg.get_int("max_steps"));
  if (task == Task::kKicker) ghost_worlds_.resize(static_cast<std::size_t>(cfg.get_int("ghost_balls")));
  warm_up_box2d();
}

EnvironmentInfo BipedalEnvironment::info() const {
  EnvironmentInfo info;
  info.observation_size = observation_size(options_.task);
  info.action_size = kActionSize;
  info.max_steps = options_.max_steps;
  info.persistent_worlds = static_cast<int>(ghost_worlds_.size());
  return info;
}

void BipedalEnvironment::save(std::ostream& out) const {
  state::write<std::uint64_t>(out, ghost_worlds_.size());
  for (const BallWorld& w : ghost_worlds_) w.save(out);
}

void BipedalEnvironment::load(std::istream& in) {
  const auto n = state::read<std::uint64_t>(in);
  if (n != ghost_worlds_.size())
    throw StateError("the state holds " + std::to_string(n) + " ghost-ball worlds, the environment has " +
                     std::to_string(ghost_worlds_.size()));
  std::vector<BallWorld> worlds(ghost_worlds_.size());
  for (BallWorld& w : worlds) w.load(in);
  ghost_worlds_ = std::move(worlds);
}

void BipedalEnvironment::rollout(const RolloutBatch& batch, Trace* traces) const {
  if (batch.begin >= batch.end) return;
  const PolicyShape& shape = *batch.shape;
  if (shape.inputs() != observation_size(options_.task) || shape.outputs() != kActionSize)
    throw std::invalid_argument("bipedal: policy shape " + std::to_string(shape.inputs()) + " -> " +
                                std::to_string(shape.outputs()) + " does not match the environment (" +
                                std::to_string(observation_size(options_.task)) + " -> 4)");
  Policy policy(shape);
  BallWorld* ghosts = nullptr;
  if (batch.world >= 0) {
    if (static_cast<std::size_t>(batch.world) >= ghost_worlds_.size() || batch.end - batch.begin != 1)
      throw std::invalid_argument("bipedal: world " + std::to_string(batch.world) + " for rows [" +
                                  std::to_string(batch.begin) + ", " + std::to_string(batch.end) + "), but " +
                                  std::to_string(ghost_worlds_.size()) + " persistent worlds and one row per call");
    ghosts = &ghost_worlds_[static_cast<std::size_t>(batch.world)];
  }
  for (std::size_t i = batch.begin; i < batch.end; ++i) {
    policy.load(batch.row(i));
    run_episode(options_, policy, traces[i], nullptr, ghosts);
  }
}

}  // namespace qd::bipedal
