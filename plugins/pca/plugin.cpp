#include "pca.hpp"

#include <qd/plugin.hpp>

QD_PLUGIN("pca", "0.1.0",
          qd::component<qd::pca::PcaRepresentation>(
              qd::Kind::kRepresentation, "pca",
              "Exact PCA of the dataset, refitted every loop; decoder Jacobian is the constant W^T.", qd::pca::kParams))
