// Plugin entry: the two biped environments and their descriptors.
#include <qd/plugin.hpp>

#include "bipedal.hpp"

QD_PLUGIN("bipedal", "0.1.0",
          qd::environment<qd::bipedal::WalkerEnvironment>(
              "bipedal-walker", "Gym BipedalWalker on the seed-100 terrain, started mid-terrain (PoMS walker).",
              qd::bipedal::kWalkerParams, "walker-gait"),
          qd::environment<qd::bipedal::KickerEnvironment>(
              "bipedal-kicker", "Gym BipedalWalker robot kicking a ball on flat ground (PoMS kicker).",
              qd::bipedal::kKickerParams, "kicker-ball"),
          qd::component<qd::bipedal::WalkerGaitDescriptor>(
              qd::Kind::kDescriptor, "walker-gait",
              "Mean hull y x final hull x x left/right contact fractions (5x100x5x5).", qd::bipedal::kWalkerGaitParams),
          qd::component<qd::bipedal::KickerBallDescriptor>(qd::Kind::kDescriptor, "kicker-ball",
                                                           "Max ball height x final ball x (50x200)."))
