// Calls itself "other_name" while its file is qd_wrong_name.so.
#include <qd/plugin.hpp>
namespace {
class M final : public qd::Mutator {
 public:
  M(const qd::Config&, const qd::BuildContext&) {}
  void mutate(const qd::Parents&, std::size_t, qd::MutateContext&, qd::Offspring&) override {}
};
}  // namespace
QD_PLUGIN("other_name", "1", qd::component<M>(qd::Kind::kMutator, "test-wrong-name", "test"))
