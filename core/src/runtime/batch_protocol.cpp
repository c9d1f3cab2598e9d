#include "runtime/batch_protocol.hpp"

#include "runtime/plugin_call.hpp"

#include <algorithm>
#include <exception>
#include <limits>

namespace qd::runtime {

void unpack_records(const double* records, std::size_t begin, std::size_t end, std::size_t dims, Evaluations& out) {
  const std::size_t w = record_width(dims);
  for (std::size_t i = begin; i < end; ++i) {
    const double* r = records + (i - begin) * w;
    out.status[i] = static_cast<EvalStatus>(static_cast<int>(r[0]));
    out.steps[i] = static_cast<std::int32_t>(r[1]);
    out.fitness[i] = r[2];
    // A cell beyond int64 (a broken descriptor's) saturates instead of overflowing the conversion;
    // the output checks refuse it either way.
    out.cells[i] = r[3] >= 0x1p63   ? std::numeric_limits<std::int64_t>::max()
                   : r[3] < -0x1p63 ? std::numeric_limits<std::int64_t>::min()
                                    : static_cast<std::int64_t>(r[3]);
    for (std::size_t d = 0; d < dims; ++d)
      out.descriptors(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(d)) = r[kRecordHead + d];
  }
}

namespace {
std::string what_of(const std::exception_ptr& e) {
  try {
    std::rethrow_exception(e);
  } catch (const std::exception& x) {
    return x.what();
  } catch (...) {
    return "an exception that is not a std::exception";
  }
}
}  // namespace

void guarded_rollout(const Environment& env, const std::string& label, const RolloutBatch& b, Trace* traces,
                     std::size_t offset) {
  const PluginCallScope scope(label, "rollout()");
  std::exception_ptr error;
  try {
    env.rollout(b, traces);
    return;
  } catch (...) {
    error = std::current_exception();
  }
  if (b.end - b.begin > 1) {
    for (std::size_t i = b.begin; i < b.end; ++i) {
      RolloutBatch one = b;
      one.begin = i;
      one.end = i + 1;
      traces[i].clear();
      try {
        env.rollout(one, traces);
      } catch (...) {
        throw EvaluationFault(label + " threw from rollout(): " + what_of(std::current_exception()), offset + i,
                              offset + i);
      }
    }
  }
  throw EvaluationFault(label + " threw from rollout(): " + what_of(error), offset + b.begin, offset + b.end - 1);
}

void guarded_describe(const Descriptor& desc, const std::string& label, const Trace& t, std::int64_t* cell,
                      double* values, std::size_t offspring) {
  const PluginCallScope scope(label, "describe()");
  try {
    desc.describe(&t, 1, cell, values);
  } catch (...) {
    throw EvaluationFault(label + " threw from describe(): " + what_of(std::current_exception()), offspring, offspring);
  }
}

RowEvaluator::RowEvaluator(const Environment& env, const Descriptor& desc, const PolicyShape& shape,
                           PluginLabels labels)
    : env_(env), desc_(desc), shape_(shape), labels_(std::move(labels)), dims_(desc.grid().dims()) {}

void RowEvaluator::run(const double* params, const std::uint64_t* seeds, std::size_t rows, double* records,
                       std::size_t first_row, std::atomic<std::uint64_t>* current) {
  if (traces_.size() < rows) traces_.resize(rows);
  // The environment reads the rows where they are (shared memory for worker processes): no copy.
  evaluate(RolloutBatch{&shape_, params, seeds, 0, rows}, traces_.data(), records, first_row, current);
}

void RowEvaluator::evaluate(RolloutBatch b, Trace* traces, double* records, std::size_t offset,
                            std::atomic<std::uint64_t>* current) const {
  b.shape = &shape_;
  for (std::size_t i = b.begin; i < b.end; ++i) traces[i].clear();
  if (!current) {
    guarded_rollout(env_, labels_.environment, b, traces, offset);
  } else {
    for (std::size_t i = b.begin; i < b.end; ++i) {
      current->store(progress_code(offset + i, false), std::memory_order_relaxed);
      RolloutBatch one = b;
      one.begin = i;
      one.end = i + 1;
      guarded_rollout(env_, labels_.environment, one, traces, offset);
    }
  }
  const std::size_t w = record_width(dims_);
  for (std::size_t i = b.begin; i < b.end; ++i) {
    double* r = records + (i - b.begin) * w;
    const Trace& t = traces[i];
    std::int64_t cell = -1;
    std::fill(r + kRecordHead, r + w, 0.0);
    if (t.status == EvalStatus::kOk) {
      if (current) current->store(progress_code(offset + i, true), std::memory_order_relaxed);
      guarded_describe(desc_, labels_.descriptor, t, &cell, r + kRecordHead, offset + i);
    }
    r[0] = static_cast<double>(static_cast<int>(t.status));
    r[1] = static_cast<double>(t.steps);
    r[2] = t.fitness;
    r[3] = static_cast<double>(cell);
  }
  if (current) current->store(0, std::memory_order_relaxed);
}

}  // namespace qd::runtime
