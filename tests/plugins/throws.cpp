// Factories that throw: a plain exception and a ConfigError naming a key.
#include <qd/plugin.hpp>
#include <stdexcept>
namespace {
constexpr qd::ParamSpec kParams[] = {qd::param_float("rate", "0.5", 0.0, 1.0, "test")};
class Throws final : public qd::Mutator {
 public:
  Throws(const qd::Config&, const qd::BuildContext&) { throw std::runtime_error("deliberate failure in the factory"); }
  void mutate(const qd::Parents&, std::size_t, qd::MutateContext&, qd::Offspring&) override {}
};
class ThrowsConfig final : public qd::Mutator {
 public:
  ThrowsConfig(const qd::Config&, const qd::BuildContext&) {
    throw qd::ConfigError("rate", "rate must not be 0.5 here");
  }
  void mutate(const qd::Parents&, std::size_t, qd::MutateContext&, qd::Offspring&) override {}
};
}  // namespace
QD_PLUGIN("throws", "1", qd::component<Throws>(qd::Kind::kMutator, "test-throws", "test"),
          qd::component<ThrowsConfig>(qd::Kind::kMutator, "test-throws-config", "test", kParams))
