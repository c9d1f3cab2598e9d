// MAPE-DDE mutator "dde" (README.md): a UCB bandit over nine mixtures of three operators,
// (a) reconstruction "crossover" ½(θ + Dec(Enc(θ))), (b) Iso+LineDD, (c) Iso.
#pragma once

#include "line_dd_ops.hpp"

#include <qd/config.hpp>
#include <qd/mutator.hpp>

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace qd::dde {

inline constexpr ParamSpec kDdeParams[] = {
    param_float("line_dd_iso_sigma", "0.003", 0.0, kUnbounded,
                "isotropic std of operator (b) Iso+LineDD (reference: hard-coded 0.003)"),
    param_float("line_dd_line_sigma", "0.1", 0.0, kUnbounded,
                "line std of operator (b) Iso+LineDD (reference: hard-coded 0.1)"),
    param_float("iso_sigma", "0.003", 0.0, kUnbounded, "std of operator (c) Iso (reference: hard-coded 0.003)"),
    param_string("update", "\"reference\"", "reference|ucb1",
                 "bandit value update: reference = v += (r·e_a − v)/f over all arms (unchosen arms decay), "
                 "then f_a += 1; ucb1 = f_a += 1, v_a += (r − v_a)/f_a"),
    param_string("reward", "\"insertions\"", "insertions|new-cells",
                 "reward numerator: insertions = added + replaced (reference), new-cells = added only"),
    param_bool("random_first_arm", "true",
               "iteration 0 of every loop plays a uniformly random arm (reference); false = UCB there too"),
    param_string("line_dd_pairing", "\"reference\"", "reference|swap",
                 "partner derangement of operator (b), see the line_dd plugin"),
};

inline constexpr std::size_t kArmCount = 9;
// Fractions of the batch given to (a), (b), (c); (c) actually takes whatever (a) and (b) leave.
inline constexpr double kArms[kArmCount][3] = {
    {0.00, 0.00, 1.00}, {0.25, 0.00, 0.75}, {0.50, 0.00, 0.50}, {0.75, 0.00, 0.25}, {1.00, 0.00, 0.00},
    {0.00, 0.25, 0.75}, {0.00, 0.50, 0.50}, {0.00, 0.75, 0.25}, {0.00, 1.00, 0.00},
};

struct ArmSplit {
  std::size_t crossover = 0;  // (a)
  std::size_t line_dd = 0;    // (b)
  std::size_t iso = 0;        // (c)
};

// n_a = int(f_a·count), n_b = int(f_b·count), n_c = the rest.
ArmSplit split_for_arm(std::size_t arm, std::size_t count);

class DdeMutator final : public Mutator {
 public:
  enum class Update { kReference, kUcb1 };

  DdeMutator(const Config& cfg, const BuildContext& ctx);

  bool needs_latent() const noexcept override { return true; }
  std::vector<std::string> metric_names() const override { return {"arm", kMixingRatio}; }

  void mutate(const Parents& parents, std::size_t count, MutateContext& ctx, Offspring& out) override;
  void feedback(const Feedback& fb) override;

  void save(std::ostream& out) const override;
  void load(std::istream& in) override;

  // Bandit state, for tests and diagnostics.
  const std::array<double, kArmCount>& values() const noexcept { return values_; }
  const std::array<std::int64_t, kArmCount>& counts() const noexcept { return counts_; }
  int current_arm() const noexcept { return arm_; }

 private:
  std::size_t ucb_arm() const;
  void update(std::size_t arm, double reward);

  line_dd::IsoLineParams line_params_;
  double iso_sigma_;
  Update update_;
  bool count_replacements_;
  bool random_first_arm_;

  // Initialised at construction, i.e. at loop 1 as in the reference, then kept across loops.
  std::array<double, kArmCount> values_{};
  std::array<std::int64_t, kArmCount> counts_{};
  int arm_ = -1;                     // arm of the last mutate()
  std::uint64_t pending_count_ = 0;  // offspring of the last mutate() awaiting feedback(); 0 = none
};

}  // namespace qd::dde
