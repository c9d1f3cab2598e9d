// Plugin qd_line_dd.so: the MAPE-IsoLineDD baseline.
#include "iso_line_dd_mutator.hpp"

#include <qd/plugin.hpp>

QD_PLUGIN("line_dd", "0.1.0",
          qd::component<qd::line_dd::IsoLineDdMutator>(
              qd::Kind::kMutator, "iso-line-dd",
              "MAP-Elites Iso+LineDD: partner + isotropic noise + Gaussian step along the parent-partner line.",
              qd::line_dd::kIsoLineDdParams))
