#include "cvt.hpp"

#include <qd/plugin.hpp>

using namespace qd;
using namespace qd::cvt;

QD_PLUGIN("cvt", "0.1.0",
          descriptor_adapter<CvtDescriptor>(
              "cvt",
              "CVT archive: the nearest of k-means centroids in the values of the descriptor it wraps "
              "([descriptor.wraps], by default the environment's own).",
              kCvtParams))
