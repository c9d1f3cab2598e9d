#include "arm.hpp"

#include <qd/plugin.hpp>

using namespace qd;
using namespace qd::arm;

QD_PLUGIN(
    "arm", "0.1.0",
    environment<ArmEnvironment>("arm",
                                "Planar arm driven by the policy, no physics engine (fast; tests and quick start).",
                                kArmParams, "arm-endpoint"),
    component<EndpointDescriptor>(Kind::kDescriptor, "arm-endpoint",
                                  "Final end-effector position on a bins x bins grid over [-1, 1]^2.", kEndpointParams))
