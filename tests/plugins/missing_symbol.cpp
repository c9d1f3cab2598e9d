// A plugin that needs a function nobody defines. qd_add_plugin links with --no-undefined, which
// would catch it at link time; this one is linked without (tests/plugins/CMakeLists.txt), as a
// hand-made build might be, so the host meets the undefined symbol at dlopen.
#include <qd/plugin.hpp>

int qd_test_symbol_defined_nowhere(int);

namespace {
class M final : public qd::Mutator {
 public:
  M(const qd::Config&, const qd::BuildContext&) : value_(qd_test_symbol_defined_nowhere(1)) {}
  void mutate(const qd::Parents&, std::size_t, qd::MutateContext&, qd::Offspring&) override {}

 private:
  int value_;
};
}  // namespace
QD_PLUGIN("missing_symbol", "1", qd::component<M>(qd::Kind::kMutator, "test-missing-symbol", "test"))
