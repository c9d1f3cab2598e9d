// MAPE-IsoLineDD mutator "iso-line-dd" (README.md).
#pragma once

#include "line_dd_ops.hpp"

#include <qd/config.hpp>
#include <qd/mutator.hpp>

namespace qd::line_dd {

inline constexpr ParamSpec kIsoLineDdParams[] = {
    param_float("iso_sigma", "0.01", 0.0, kUnbounded,
                "std of the isotropic Gaussian step (reference: hard-coded 0.01; the config sigma is ignored)"),
    param_float("line_sigma", "0.2", 0.0, kUnbounded,
                "std of the scalar step along the partner direction (reference: hard-coded 0.2)"),
    param_string("pairing", "\"reference\"", "reference|swap",
                 "partner derangement: reference = numpy vectorised fix-up (rarely duplicates a partner), "
                 "swap = sequential swaps (always a permutation)"),
};

class IsoLineDdMutator final : public Mutator {
 public:
  IsoLineDdMutator(const Config& cfg, const BuildContext& ctx);
  std::vector<std::string> metric_names() const override { return {kMixingRatio}; }

  void mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) override;

 private:
  IsoLineParams params_;
};

}  // namespace qd::line_dd
