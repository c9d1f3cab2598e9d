#include "lp.hpp"

#include <qd/plugin.hpp>

using namespace qd;
using namespace qd::lp;

QD_PLUGIN(
    "lp", "0.1.0",
    environment<LpSphere>("lp-sphere",
                          "CMA-ME paper's linear-projection sphere: n plain parameters, fitness in [0, 100].",
                          kLpParams, "lp-measures"),
    environment<LpRastrigin>("lp-rastrigin",
                             "CMA-ME paper's linear-projection Rastrigin: n plain parameters, fitness in [0, 100].",
                             kLpParams, "lp-measures"),
    component<MeasuresDescriptor>(Kind::kDescriptor, "lp-measures",
                                  "The two clipped linear-projection measures on a bins x bins grid.", kMeasuresParams))
