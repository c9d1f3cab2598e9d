// The "striker" environment component: air-hockey Striker of the PoMS paper (README.md).
#pragma once

#include "striker_sim.hpp"

#include <qd/config.hpp>
#include <qd/environment.hpp>

namespace qd::striker {

inline constexpr ParamSpec kEnvironmentParams[] = {
    param_bool("mix_scale", "false",
               "multiply six observation entries (mix_scale_elements) by 100 (StrikerAugmentedMixScale)"),
    param_string("mix_scale_elements", "\"companion\"", "companion|paper",
                 "with mix_scale: companion = puck position and wall distances (obs 3, 4, 10-13; the companion "
                 "code); paper = striker position, puck position and velocity (obs 0, 1, 3, 4, 8, 9; the paper's "
                 "text)"),
    param_bool("puck_hits_target", "false",
               "false = reference quirk: the target circle blocks only the striker; true: the puck collides "
               "with it too"),
    param_int("max_steps", "1000", kRowEvery, 1e9, "episode length limit; max_steps / 20 trajectory rows are kept"),
};

class StrikerEnvironment final : public Environment {
 public:
  StrikerEnvironment(const Config& config, const BuildContext& context);
  explicit StrikerEnvironment(const Options& options);

  EnvironmentInfo info() const override;
  void rollout(const RolloutBatch& batch, Trace* traces) const override;
  bool draw_svg(const Trace& trace, std::ostream& out) const override;

  const Options& options() const noexcept { return options_; }

 private:
  Options options_;
};

}  // namespace qd::striker
