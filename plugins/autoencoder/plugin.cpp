// Registers the PoMS autoencoder as representation "autoencoder".
#include "autoencoder.hpp"

#include <qd/plugin.hpp>

QD_PLUGIN("autoencoder", "0.1.0",
          qd::component<qd::autoencoder::Autoencoder>(
              qd::Kind::kRepresentation, "autoencoder",
              "PoMS parameter autoencoder P-HD(ELU)-LD-HD(ELU)-P, Adam on per-sample SSE, closed-form Jacobians.",
              qd::autoencoder::kParams))
