// Plugin qd_dde.so: the MAPE-DDE baseline.
#include "dde_mutator.hpp"

#include <qd/plugin.hpp>

QD_PLUGIN("dde", "0.1.0",
          qd::component<qd::dde::DdeMutator>(
              qd::Kind::kMutator, "dde",
              "MAP-Elites DDE: UCB bandit over reconstruction crossover / Iso+LineDD / Iso batch mixtures.",
              qd::dde::kDdeParams))
