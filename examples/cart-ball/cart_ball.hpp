// cart-ball: an environment and a descriptor written outside the qdrun tree (docs/plugin-guide.md).
// A cart driven by the policy bats a ball dropped onto it; the descriptor bins which way the ball
// rolls at the end, where it ends up and how high it went. The fitness is the highest point.
#pragma once

#include <qd/config.hpp>
#include <qd/descriptor.hpp>
#include <qd/environment.hpp>
#include <qd/policy.hpp>

#include <box2d/box2d.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace cart_ball {

inline constexpr float kTimeStep = 1.0f / 60.0f;
inline constexpr int kRecordEvery = 10;  // one trajectory row every 10 steps, plus the first and the last

inline constexpr qd::ParamSpec kCartBallParams[] = {
    qd::param_int("steps", "180", 10, 100000, "world steps per episode (1/60 s each)"),
    qd::param_float("speed", "4", 0.0, qd::kUnbounded, "cart speed (units/s) per axis at action 1"),
};

// Box2D 2.4.1 fills a global table at the first contact of the process, without a lock. Making one
// contact here, while qdrun builds the components on its main thread, keeps rollouts thread-safe.
inline void warm_up_box2d() {
  b2World world(b2Vec2(0.0f, -10.0f));
  b2BodyDef ground_def;
  b2PolygonShape box;
  box.SetAsBox(1.0f, 1.0f);
  world.CreateBody(&ground_def)->CreateFixture(&box, 0.0f);
  b2BodyDef ball_def;
  ball_def.type = b2_dynamicBody;
  ball_def.position.Set(0.5f, 0.5f);  // overlaps the box
  b2CircleShape circle;
  circle.m_radius = 1.0f;
  world.CreateBody(&ball_def)->CreateFixture(&circle, 1.0f);
  world.Step(kTimeStep, 8, 3);
}

class CartBall final : public qd::Environment {
 public:
  CartBall(const qd::Config& cfg, const qd::BuildContext&)
      : steps_(static_cast<int>(cfg.get_int("steps"))), speed_(static_cast<float>(cfg.get_float("speed"))) {
    warm_up_box2d();
  }

  // Observation: cart x, y, ball x, y, vx, vy, episode phase. Action: cart velocity (x, y).
  // Fitness: the ball's highest point (metrics.csv's max_fitness and mean_fitness; no lower bound is
  // declared, so qd_score stays empty unless the experiment file gives [experiment] fitness_lower_bound).
  qd::EnvironmentInfo info() const override {
    qd::EnvironmentInfo info{7, 2, steps_};
    info.has_fitness = true;
    return info;
  }

  // Stateless and const: every episode builds its own world, so any worker can run any policy.
  void rollout(const qd::RolloutBatch& batch, qd::Trace* traces) const override {
    qd::Policy policy(*batch.shape);  // one per call: a Policy is not thread-safe
    for (std::size_t i = batch.begin; i < batch.end; ++i) {
      policy.load(batch.row(i));
      episode(policy, traces[i]);
    }
  }

 private:
  void episode(qd::Policy& policy, qd::Trace& t) const {
    b2World world(b2Vec2(0.0f, -10.0f));
    b2BodyDef ground_def;
    b2EdgeShape floor;
    floor.SetTwoSided(b2Vec2(-50.0f, 0.0f), b2Vec2(50.0f, 0.0f));
    world.CreateBody(&ground_def)->CreateFixture(&floor, 0.0f);
    b2BodyDef cart_def;
    cart_def.type = b2_kinematicBody;
    cart_def.position.Set(0.0f, 0.15f);
    b2Body* cart = world.CreateBody(&cart_def);
    b2PolygonShape box;
    box.SetAsBox(0.6f, 0.15f);
    cart->CreateFixture(&box, 1.0f);
    b2BodyDef ball_def;
    ball_def.type = b2_dynamicBody;
    ball_def.position.Set(0.2f, 0.6f);
    b2Body* ball = world.CreateBody(&ball_def);
    b2CircleShape circle;
    circle.m_radius = 0.15f;
    b2FixtureDef fixture;
    fixture.shape = &circle;
    fixture.density = 1.0f;
    fixture.friction = 0.3f;
    fixture.restitution = 0.7f;
    ball->CreateFixture(&fixture);

    t.main.reset(3);  // ball x, y, vx
    record(*ball, t);
    float height = ball->GetPosition().y;
    for (int step = 0; step < steps_; ++step) {
      const b2Vec2 c = cart->GetPosition(), p = ball->GetPosition(), v = ball->GetLinearVelocity();
      const float obs[7] = {c.x, c.y, p.x, p.y, v.x, v.y, static_cast<float>(step) / steps_};
      const float* a = policy.act(obs);
      if (!std::isfinite(a[0]) || !std::isfinite(a[1])) {  // an outcome, not an exception: not inserted
        t.status = qd::EvalStatus::kInvalidAction;
        t.message = "non-finite action at step " + std::to_string(step);
        return;
      }
      float vy = speed_ * std::clamp(a[1], -1.0f, 1.0f);
      if ((c.y <= 0.15f && vy < 0.0f) || (c.y >= 2.0f && vy > 0.0f)) vy = 0.0f;  // between floor and y = 2
      cart->SetLinearVelocity(b2Vec2(speed_ * std::clamp(a[0], -1.0f, 1.0f), vy));
      world.Step(kTimeStep, 8, 3);
      t.steps = step + 1;
      if (!std::isfinite(ball->GetPosition().x) || !std::isfinite(ball->GetPosition().y)) {
        t.status = qd::EvalStatus::kDiverged;
        t.message = "ball position not finite";
        return;
      }
      height = std::max(height, ball->GetPosition().y);
      if ((step + 1) % kRecordEvery == 0 || step + 1 == steps_) record(*ball, t);
    }
    t.fitness = height;
  }

  static void record(const b2Body& ball, qd::Trace& t) {
    t.main.push(ball.GetPosition().x, ball.GetPosition().y, ball.GetLinearVelocity().x);
  }

  int steps_;
  float speed_;
};

// int(clamp((v - lo) / (hi - lo) * n, 0, n - 1)); -1 for a non-finite value.
inline int bin(double v, double lo, double hi, int n) {
  if (!std::isfinite(v)) return -1;
  return static_cast<int>(std::clamp((v - lo) / (hi - lo) * n, 0.0, n - 1.0));
}

// Three dimensions, in the order of the cell index (row-major, the last fastest): which way the ball
// rolls at the end (named bins: left, still, right), where it ends, and its highest point; so a
// map draws one panel per direction, the final x to the right and the height up.
class Landing final : public qd::Descriptor {
 public:
  Landing(const qd::Config&, const qd::BuildContext&) {}

  qd::GridSpec grid() const override {
    qd::GridSpec g;
    g.shape = {3, 24, 8};
    g.names = {"direction", "final_x", "max_height"};
    g.lower = {0.0, -6.0, 0.0};
    g.upper = {3.0, 6.0, 4.0};
    g.cells = 3 * 24 * 8;
    g.labels = {{"left", "still", "right"}, {}, {}};  // names of the bins, for plots (grid.toml)
    return g;
  }

  void describe(const qd::Trace* traces, std::size_t n, std::int64_t* cells, double* values) const override {
    for (std::size_t i = 0; i < n; ++i) {
      const qd::Series& rows = traces[i].main;
      cells[i] = -1;  // not described: not inserted
      if (rows.cols != 3 || rows.rows() == 0) continue;
      double height = 0.0;
      for (std::size_t r = 0; r < rows.rows(); ++r) height = std::max(height, rows.at(r, 1));
      const double vx = rows.last()[2];
      const double direction = vx < -0.05 ? 0.0 : vx > 0.05 ? 2.0 : 1.0;
      double* out = values + 3 * i;  // the continuous values, one per dimension
      out[0] = direction;
      out[1] = rows.last()[0];
      out[2] = height;
      const int x = bin(out[1], -6.0, 6.0, 24), h = bin(height, 0.0, 4.0, 8);
      if (h < 0 || x < 0) continue;
      cells[i] = (static_cast<std::int64_t>(direction) * 24 + x) * 8 + h;
    }
  }
};

}  // namespace cart_ball
