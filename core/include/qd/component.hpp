// Common base of everything a plugin makes, and what a factory receives besides its table.
#pragma once

#include <qd/export.hpp>
#include <qd/policy.hpp>

#include <cstdint>

namespace qd {

class Descriptor;
struct GridSpec;

// Base of Environment, Descriptor, Representation and Mutator. Not copyable. The destructor is
// defined in the core library (the key function that pins type information there, which makes
// dynamic_cast and exceptions work across plugin boundaries).
class QD_EXPORT Component {
 public:
  Component() = default;
  Component(const Component&) = delete;
  Component& operator=(const Component&) = delete;
  virtual ~Component();
};

// Run-wide facts a factory may need. Components are built in this order: environment, the
// descriptor a descriptor adapter wraps, descriptor (policy known from here on), representation,
// mutators.
struct BuildContext {
  std::uint64_t seed = 0;               // the run seed; derive streams with qd::Rng
  const PolicyShape* policy = nullptr;  // null while the environment is being built
  int latent_size = 0;                  // the representation's latent size (mutators only)
  int batch = 0;                        // offspring per iteration, [experiment] batch (mutators only)
  // Descriptor adapters only: the descriptor they wrap (built by the core, alive as long as the
  // adapter).
  const Descriptor* wrapped = nullptr;
  // Descriptors only, when an existing run is opened (--resume, --replay, --latents): the grid the
  // run was made with, as its run directory stores it (a CVT's centroids.csv). A descriptor that
  // computes its grid reuses it, so that a resumed run keeps its cells exactly. Null otherwise.
  const GridSpec* stored_grid = nullptr;
};

}  // namespace qd
