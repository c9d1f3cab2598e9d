// The plugin library qd_cart_ball.so: registers the environment and descriptor of cart_ball.hpp.
#include "cart_ball.hpp"

#include <qd/plugin.hpp>

QD_PLUGIN("cart_ball", "0.1.0",
          qd::environment<cart_ball::CartBall>(
              "cart-ball", "A cart bats a falling ball (Box2D); the out-of-tree example of examples/.",
              cart_ball::kCartBallParams, "cart-ball-landing"),
          qd::component<cart_ball::Landing>(qd::Kind::kDescriptor, "cart-ball-landing",
                                            "Final rolling direction x final position x highest point of the ball."))
