// The plugin library qd_half_step.so: registers the mutator of half_step.hpp.
#include "half_step.hpp"

#include <qd/plugin.hpp>

QD_PLUGIN("half_step", "0.0.1",
          qd::component<half_step::HalfStep>(qd::Kind::kMutator, "half-step", "Move halfway to a random point.",
                                             half_step::kParams))
