#include "cma_me_mutator.hpp"

#include <qd/errors.hpp>
#include <qd/state_io.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace qd::cma_me {

std::vector<std::size_t> improvement_ranking(const std::vector<OffspringResult>& results, std::size_t begin,
                                             std::size_t end) {
  std::vector<RankKey> keys;
  for (std::size_t k = begin; k < end; ++k) {
    const OffspringResult& r = results[k];
    const int stage = r.outcome == Outcome::kNewCell ? 2 : r.entered() ? 1 : 0;
    const double value = std::isnan(r.change()) ? -std::numeric_limits<double>::infinity() : r.change();
    keys.push_back({stage, value, k});
  }
  std::stable_sort(keys.begin(), keys.end(), [](const RankKey& a, const RankKey& b) {
    return a.stage != b.stage ? a.stage > b.stage : a.value > b.value;
  });
  std::vector<std::size_t> order;
  for (const RankKey& key : keys) order.push_back(key.k);
  return order;
}

CmaMeMutator::CmaMeMutator(const Config& cfg, const BuildContext& ctx)
    : emitter_count_(static_cast<std::size_t>(cfg.get_int("emitters"))),
      sigma0_(cfg.get_float("sigma0")),
      filter_(cfg.get_string("selection") == "filter"),
      restart_on_no_improvement_(cfg.get_string("restart") == "no-improvement") {
  if (ctx.batch > 0) {
    const auto batch = static_cast<std::size_t>(ctx.batch);
    if (batch % emitter_count_ != 0 || batch / emitter_count_ < 2)
      throw ConfigError("emitters", "[experiment] batch = " + std::to_string(batch) +
                                        " must be a multiple of emitters = " + std::to_string(emitter_count_) +
                                        ", with at least 2 offspring per emitter (the paper: 15 emitters of 37)");
  }
}

void CmaMeMutator::start(std::size_t count, std::size_t params) {
  if (count % emitter_count_ != 0 || count / emitter_count_ < 2)
    throw std::invalid_argument("cma-me: a batch of " + std::to_string(count) + " is not a multiple of emitters = " +
                                std::to_string(emitter_count_) + " with at least 2 offspring each");
  lambda_ = count / emitter_count_;
  params_ = params;
  emitters_.clear();
  for (std::size_t e = 0; e < emitter_count_; ++e)
    emitters_.push_back({std::make_unique<CmaEs>(params_, lambda_, sigma0_), true});
}

void CmaMeMutator::mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) {
  const auto p = static_cast<std::size_t>(out.theta.cols());
  if (emitters_.empty()) start(count, p);
  if (count != lambda_ * emitter_count_ || p != params_)
    throw std::invalid_argument("cma-me: the batch changed shape between iterations");
  QD_CHECK(parents.theta.rows() > 0, "cma-me draws its restarts from the selected parents");
  double sigma = 0.0;
  for (std::size_t e = 0; e < emitter_count_; ++e) {
    Emitter& em = emitters_[e];
    if (em.restart_pending) {
      const auto row = static_cast<Eigen::Index>(e % static_cast<std::size_t>(parents.theta.rows()));
      em.es->reset(parents.theta.row(row).data());
      em.restart_pending = false;
      ++restarts_;
    }
    em.es->sample(*ctx.rng, out.theta.row(static_cast<Eigen::Index>(e * lambda_)).data());
    sigma += em.es->sigma();
  }
  samples_ = out.theta;
  // Restarts so far (the first start of each emitter counts), and the emitters' mean step size.
  out.metrics = {static_cast<double>(restarts_), sigma / static_cast<double>(emitter_count_)};
}

void CmaMeMutator::feedback(const Feedback& fb) {
  if (emitters_.empty() || fb.results == nullptr) return;
  const std::vector<OffspringResult>& results = *fb.results;
  QD_CHECK(results.size() == lambda_ * emitter_count_ && samples_.rows() == static_cast<Eigen::Index>(results.size()),
           "cma-me: feedback for another batch than the one it made");
  for (std::size_t e = 0; e < emitter_count_; ++e) {
    Emitter& em = emitters_[e];
    const std::size_t begin = e * lambda_, end = begin + lambda_;
    const std::vector<std::size_t> order = improvement_ranking(results, begin, end);
    std::size_t entered = 0;
    for (std::size_t k = begin; k < end; ++k) entered += results[k].entered();
    const std::size_t mu = filter_ ? entered : lambda_ / 2;
    if (mu > 0) {
      Matrix best(static_cast<Eigen::Index>(mu), static_cast<Eigen::Index>(params_));
      for (std::size_t i = 0; i < mu; ++i)
        best.row(static_cast<Eigen::Index>(i)) = samples_.row(static_cast<Eigen::Index>(order[i]));
      em.es->tell(best);
    } else {
      em.es->skip();
    }
    // A flat ranking (first and last alike) gives CMA-ES nothing to adapt to: pycma's tolfun stop.
    const OffspringResult &first = results[order.front()], &last = results[order.back()];
    const bool flat = (first.outcome == Outcome::kNewCell) == (last.outcome == Outcome::kNewCell) &&
                      first.entered() == last.entered() && std::fabs(first.change() - last.change()) < 1e-12;
    if ((restart_on_no_improvement_ && entered == 0) || em.es->converged() || flat) em.restart_pending = true;
  }
}

void CmaMeMutator::save(std::ostream& out) const {
  state::write_tag(out, "CMME");
  state::write<std::uint64_t>(out, emitter_count_);
  state::write<std::uint64_t>(out, lambda_);
  state::write<std::uint64_t>(out, params_);
  state::write<std::uint64_t>(out, restarts_);
  for (const Emitter& em : emitters_) {
    state::write<std::uint8_t>(out, em.restart_pending ? 1 : 0);
    em.es->save(out);
  }
}

void CmaMeMutator::load(std::istream& in) {
  state::expect_tag(in, "CMME");
  if (state::read<std::uint64_t>(in) != emitter_count_) throw StateError("cma-me state of another emitter count");
  const auto lambda = state::read<std::uint64_t>(in);
  const auto params = state::read<std::uint64_t>(in);
  const auto restarts = state::read<std::uint64_t>(in);
  emitters_.clear();
  if (lambda > 0) start(static_cast<std::size_t>(lambda) * emitter_count_, static_cast<std::size_t>(params));
  restarts_ = restarts;
  for (Emitter& em : emitters_) {
    em.restart_pending = state::read<std::uint8_t>(in) != 0;
    em.es->load(in);
  }
}

}  // namespace qd::cma_me
