#include "cma_me_mutator.hpp"

#include <qd/plugin.hpp>

using namespace qd;
using namespace qd::cma_me;

QD_PLUGIN("cma_me", "0.1.0",
          component<CmaMeMutator>(Kind::kMutator, "cma-me",
                                  "CMA-ME: improvement emitters, each a CMA-ES, ranked by the archive's response.",
                                  kCmaMeParams))
