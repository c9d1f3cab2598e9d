#include "arm.hpp"

#include <qd/policy.hpp>

#include <algorithm>
#include <cmath>
#include <ostream>
#include <vector>

namespace qd::arm {

ArmEnvironment::ArmEnvironment(const Config& cfg, const BuildContext&)
    : joints_(static_cast<int>(cfg.get_int("joints"))),
      steps_(static_cast<int>(cfg.get_int("steps"))),
      record_every_(static_cast<int>(cfg.get_int("record_every"))),
      dt_(cfg.get_float("dt")),
      angle_variance_(cfg.get_string("fitness") == "angle-variance") {}

EnvironmentInfo ArmEnvironment::info() const {
  EnvironmentInfo info{joints_ + 3, joints_, steps_};
  info.has_fitness = true;
  // Each step moves a joint by at most dt and adds at most `joints` to the effort, so no policy
  // does worse than these.
  const double travel = dt_ * steps_;
  info.fitness_lower_bound = angle_variance_ ? -travel * travel : -travel * joints_;
  return info;
}

void ArmEnvironment::end_effector(const double* angles, double& x, double& y) const {
  const double link = 1.0 / joints_;
  double phi = 0.0;
  x = y = 0.0;
  for (int j = 0; j < joints_; ++j) {
    phi += angles[j];
    x += link * std::cos(phi);
    y += link * std::sin(phi);
  }
}

void ArmEnvironment::rollout(const RolloutBatch& batch, Trace* traces) const {
  Policy policy(*batch.shape);
  std::vector<double> angles(static_cast<std::size_t>(joints_));
  std::vector<float> obs(static_cast<std::size_t>(joints_ + 3));
  for (std::size_t i = batch.begin; i < batch.end; ++i) {
    Trace& t = traces[i];
    t.main.reset(2);
    t.aux.reset(joints_);
    policy.load(batch.row(i));
    std::fill(angles.begin(), angles.end(), 0.0);
    double x, y, energy = 0.0;
    end_effector(angles.data(), x, y);
    t.main.push(x, y);
    t.aux.data.insert(t.aux.data.end(), angles.begin(), angles.end());
    for (int step = 0; step < steps_; ++step) {
      for (int j = 0; j < joints_; ++j)
        obs[static_cast<std::size_t>(j)] = static_cast<float>(angles[static_cast<std::size_t>(j)]);
      obs[static_cast<std::size_t>(joints_)] = static_cast<float>(x);
      obs[static_cast<std::size_t>(joints_) + 1] = static_cast<float>(y);
      obs[static_cast<std::size_t>(joints_) + 2] = static_cast<float>(step) / static_cast<float>(steps_);
      const float* a = policy.act(obs.data());
      for (int j = 0; j < joints_; ++j) {
        if (!std::isfinite(a[j])) {
          t.status = EvalStatus::kInvalidAction;
          t.message = "non-finite action at step " + std::to_string(step);
          break;
        }
        const double v = std::clamp(static_cast<double>(a[j]), -1.0, 1.0);
        angles[static_cast<std::size_t>(j)] += dt_ * v;
        energy += v * v;
      }
      if (t.status != EvalStatus::kOk) break;
      end_effector(angles.data(), x, y);
      t.steps = step + 1;
      if ((step + 1) % record_every_ == 0 || step + 1 == steps_) {
        t.main.push(x, y);
        t.aux.data.insert(t.aux.data.end(), angles.begin(), angles.end());
      }
    }
    if (angle_variance_) {
      double mean = 0.0, var = 0.0;
      for (const double a : angles) mean += a;
      mean /= joints_;
      for (const double a : angles) var += (a - mean) * (a - mean);
      t.fitness = -var / joints_;
    } else {
      t.fitness = -energy * dt_;  // negative control effort
    }
  }
}

bool ArmEnvironment::draw_svg(const Trace& trace, std::ostream& out) const {
  out << "<svg xmlns=\"http://www.w3.org/2000/svg\" viewBox=\"-1.1 -1.1 2.2 2.2\" width=\"440\" height=\"440\">\n"
      << "<g transform=\"scale(1,-1)\"><rect x=\"-1\" y=\"-1\" width=\"2\" height=\"2\" fill=\"none\" stroke=\"#999\" "
         "stroke-width=\"0.005\"/>\n<circle cx=\"0\" cy=\"0\" r=\"1\" fill=\"none\" stroke=\"#ccc\" "
         "stroke-width=\"0.005\"/>\n"
      << "<polyline fill=\"none\" stroke=\"#1f77b4\" stroke-width=\"0.01\" points=\"";
  for (std::size_t r = 0; r < trace.main.rows(); ++r) out << trace.main.at(r, 0) << "," << trace.main.at(r, 1) << " ";
  out << "\"/>\n";
  if (trace.aux.rows() > 0) {
    // The arm in its final pose.
    const double* a = trace.aux.last();
    double px = 0, py = 0, phi = 0;
    out << "<polyline fill=\"none\" stroke=\"#333\" stroke-width=\"0.02\" points=\"0,0 ";
    for (int j = 0; j < joints_; ++j) {
      phi += a[j];
      px += std::cos(phi) / joints_;
      py += std::sin(phi) / joints_;
      out << px << "," << py << " ";
    }
    out << "\"/>\n";
  }
  out << "</g></svg>\n";
  return true;
}

EndpointDescriptor::EndpointDescriptor(const Config& cfg, const BuildContext&)
    : bins_(static_cast<int>(cfg.get_int("bins"))) {}

GridSpec EndpointDescriptor::grid() const {
  GridSpec g;
  g.shape = {bins_, bins_};
  g.names = {"y", "x"};
  g.lower = {-1.0, -1.0};
  g.upper = {1.0, 1.0};
  g.cells = static_cast<std::int64_t>(bins_) * bins_;
  return g;
}

std::int64_t EndpointDescriptor::cell_of(double x, double y) const {
  auto bin = [&](double v) {
    const double b = std::floor((v + 1.0) / 2.0 * bins_);
    return static_cast<std::int64_t>(std::clamp(b, 0.0, static_cast<double>(bins_ - 1)));
  };
  return bin(y) * bins_ + bin(x);
}

void EndpointDescriptor::describe(const Trace* traces, std::size_t n, std::int64_t* cells, double* values) const {
  for (std::size_t i = 0; i < n; ++i) {
    const Trace& t = traces[i];
    if (t.main.rows() == 0 || t.main.cols != 2) {
      cells[i] = -1;
      continue;
    }
    const double x = t.main.last()[0], y = t.main.last()[1];
    cells[i] = cell_of(x, y);
    values[2 * i] = y;
    values[2 * i + 1] = x;
  }
}

}  // namespace qd::arm
