// Registers the same name twice.
#include <qd/plugin.hpp>
namespace {
class M final : public qd::Mutator {
 public:
  M(const qd::Config&, const qd::BuildContext&) {}
  void mutate(const qd::Parents&, std::size_t, qd::MutateContext&, qd::Offspring&) override {}
};
}  // namespace
QD_PLUGIN("duplicate_inside", "1", qd::component<M>(qd::Kind::kMutator, "test-twice", "test"),
          qd::component<M>(qd::Kind::kMutator, "test-twice", "test"))
