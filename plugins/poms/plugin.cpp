#include "poms.hpp"

#include <qd/plugin.hpp>

QD_PLUGIN("poms", "0.1.0",
          qd::component<qd::poms::PomsMutator>(
              qd::Kind::kMutator, "poms",
              "PoMS region mix: high-error parents get parameter-space noise, the rest z' ~ N(Enc(theta), "
              "sigma J^T J) decoded.",
              qd::poms::kPomsParams),
          qd::component<qd::poms::NoJacobianMutator>(
              qd::Kind::kMutator, "poms-no-jacobian",
              "Latent noise scaled by the dataset's per-coordinate latent std; never mixes.",
              qd::poms::kNoJacobianParams))
