#include "basic.hpp"

#include <qd/plugin.hpp>

using namespace qd;
using namespace qd::basic;

QD_PLUGIN("basic", "0.1.0",
          component<NoRepresentation>(Kind::kRepresentation, "none", "No latent model (parameter-space algorithms)."),
          component<IsoMutator>(Kind::kMutator, "iso", "MAPE-Iso: theta + sigma * N(0, I).", kIsoParams),
          component<UniformSampler>(Kind::kMutator, "uniform",
                                    "Fresh policies, every parameter U(low, high); ps-uniform and loop-0 sampling.",
                                    kUniformParams),
          component<GlorotSampler>(Kind::kMutator, "glorot",
                                   "Fresh policies, layer l ~ N(0, 1/(n_in + 1 + n_out)); ps-glorot."))
