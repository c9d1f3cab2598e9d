// Provides "test-counted" (which the good plugin provides too), "iso" (which the in-tree basic
// plugin provides) and a name of its own: whichever library comes later in the search path loses
// only the shared names, never its other components.
#include <qd/plugin.hpp>
namespace {
class M final : public qd::Mutator {
 public:
  M(const qd::Config&, const qd::BuildContext&) {}
  void mutate(const qd::Parents& p, std::size_t, qd::MutateContext&, qd::Offspring& out) override {
    out.theta = p.theta;
  }
};
}  // namespace
QD_PLUGIN("shadow", "1", qd::component<M>(qd::Kind::kMutator, "test-counted", "test"),
          qd::component<M>(qd::Kind::kMutator, "iso", "test: shadows the built-in iso"),
          qd::component<M>(qd::Kind::kMutator, "test-shadow-own", "test"))
