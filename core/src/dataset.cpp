#include <qd/dataset.hpp>
#include <qd/errors.hpp>
#include <qd/state_io.hpp>

namespace qd {

Dataset::Dataset(std::size_t param_count) : param_count_(param_count) {}

void Dataset::add(const double* theta, std::int64_t cell, int loop) {
  QD_CHECK(!contains_cell(cell), "dataset holds one policy per cell");
  params_.insert(params_.end(), theta, theta + param_count_);
  cells_.push_back(cell);
  loops_.push_back(loop);
  cell_set_.insert(cell);
}

void Dataset::save(std::ostream& out) const {
  state::write_tag(out, "DSET");
  state::write<std::uint64_t>(out, param_count_);
  state::write_vector(out, params_);
  state::write_vector(out, cells_);
  state::write_vector(out, loops_);
}

void Dataset::load(std::istream& in) {
  state::expect_tag(in, "DSET");
  const auto p = state::read<std::uint64_t>(in);
  if (p != param_count_) throw StateError("dataset in checkpoint has a different parameter count");
  params_ = state::read_vector<double>(in);
  cells_ = state::read_vector<std::int64_t>(in);
  loops_ = state::read_vector<int>(in);
  if (params_.size() != cells_.size() * param_count_ || loops_.size() != cells_.size())
    throw StateError("dataset in checkpoint is inconsistent");
  cell_set_.clear();
  cell_set_.insert(cells_.begin(), cells_.end());
}

}  // namespace qd
