#include "striker_descriptor.hpp"
#include "striker_env.hpp"

#include <qd/plugin.hpp>

QD_PLUGIN("striker", "0.1.0",
          qd::environment<qd::striker::StrikerEnvironment>(
              "striker", "PoMS air-hockey Striker (Box2D): a velocity-commanded striker hits a puck; obs 14, action 3.",
              qd::striker::kEnvironmentParams, "striker-contacts"),
          qd::component<qd::striker::ContactGridDescriptor>(
              qd::Kind::kDescriptor, "striker-contacts",
              "First two distinct walls the puck touched (17 classes) x final puck position (30 x 30): 15300 "
              "cells."))
