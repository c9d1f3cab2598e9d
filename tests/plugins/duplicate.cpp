// Registers "test-counted", which the good plugin already provides.
#include <qd/plugin.hpp>
namespace {
class M final : public qd::Mutator {
 public:
  M(const qd::Config&, const qd::BuildContext&) {}
  void mutate(const qd::Parents&, std::size_t, qd::MutateContext&, qd::Offspring&) override {}
};
}  // namespace
QD_PLUGIN("duplicate", "1", qd::component<M>(qd::Kind::kMutator, "test-counted", "test"))
