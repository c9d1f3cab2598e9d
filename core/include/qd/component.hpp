// Common base of everything a plugin makes, and what a factory receives besides its table.
#pragma once

#include <qd/export.hpp>
#include <qd/policy.hpp>

#include <cstdint>

namespace qd {

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

// Run-wide facts a factory may need. Components are built in this order: environment,
// descriptor (policy known from here on), representation, mutators.
struct BuildContext {
  std::uint64_t seed = 0;               // the run seed; derive streams with qd::Rng
  const PolicyShape* policy = nullptr;  // null while the environment is being built
  int latent_size = 0;                  // the representation's latent size (mutators only)
};

}  // namespace qd
