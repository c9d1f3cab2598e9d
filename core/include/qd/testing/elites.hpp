// An ArchiveView over elites given row by row, for plugin tests (a mutator's begin_loop and
// mutate receive one). Header-only: it is compiled into the test that uses it.
#pragma once

#include <qd/archive.hpp>
#include <qd/types.hpp>

#include <cstdint>
#include <stdexcept>
#include <vector>

namespace qd::testing {

class Elites final : public ArchiveView {
 public:
  Elites(std::int64_t cells, std::size_t param_count, std::size_t descriptor_dims)
      : cells_(cells), params_(param_count), dims_(descriptor_dims), slot_(static_cast<std::size_t>(cells), -1) {}

  // Puts an elite into an empty cell (the next slot).
  Elites& add(std::int64_t cell, const std::vector<double>& params, double recn_error = 0.0, double fitness = 0.0,
              std::vector<double> descriptor = {}) {
    if (cell < 0 || cell >= cells_ || slot_[static_cast<std::size_t>(cell)] >= 0)
      throw std::invalid_argument("Elites::add: cell outside the grid or already filled");
    if (params.size() != params_) throw std::invalid_argument("Elites::add: wrong parameter count");
    descriptor.resize(dims_, 0.0);
    slot_[static_cast<std::size_t>(cell)] = static_cast<std::int64_t>(cell_.size());
    cell_.push_back(cell);
    theta_.insert(theta_.end(), params.begin(), params.end());
    desc_.insert(desc_.end(), descriptor.begin(), descriptor.end());
    fitness_.push_back(fitness);
    recn_.push_back(recn_error);
    return *this;
  }

  std::int64_t cells() const noexcept override { return cells_; }
  std::size_t size() const noexcept override { return cell_.size(); }
  std::size_t param_count() const noexcept override { return params_; }
  std::size_t descriptor_dims() const noexcept override { return dims_; }
  std::int64_t slot_of(std::int64_t cell) const noexcept override {
    return cell < 0 || cell >= cells_ ? -1 : slot_[static_cast<std::size_t>(cell)];
  }
  std::int64_t cell(std::size_t slot) const override { return cell_.at(slot); }
  const double* params(std::size_t slot) const override { return theta_.data() + slot * params_; }
  const double* descriptor(std::size_t slot) const override { return desc_.data() + slot * dims_; }
  double fitness(std::size_t slot) const override { return fitness_.at(slot); }
  double recn_error(std::size_t slot) const override { return recn_.at(slot); }

 private:
  std::int64_t cells_;
  std::size_t params_, dims_;
  std::vector<std::int64_t> slot_, cell_;
  std::vector<double> theta_, desc_, fitness_, recn_;
};

}  // namespace qd::testing
