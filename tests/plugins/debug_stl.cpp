// An ordinary plugin compiled with flags that change the layout of standard containers (see
// CMakeLists.txt): qd_debug_stl.so with -D_GLIBCXX_DEBUG, qd_old_abi.so with
// -D_GLIBCXX_USE_CXX11_ABI=0 (the pre-C++11 std::string). The host must refuse both before using
// anything in them.
#include <qd/plugin.hpp>

#ifndef QD_TEST_PLUGIN_NAME
#define QD_TEST_PLUGIN_NAME "debug_stl"
#define QD_TEST_COMPONENT_NAME "debug-stl-nothing"
#endif

namespace {
class Nothing final : public qd::Mutator {
 public:
  Nothing(const qd::Config&, const qd::BuildContext&) {}
  void mutate(const qd::Parents&, std::size_t, qd::MutateContext&, qd::Offspring&) override {}
};
}  // namespace

QD_PLUGIN(QD_TEST_PLUGIN_NAME, "1", qd::component<Nothing>(qd::Kind::kMutator, QD_TEST_COMPONENT_NAME, "Does nothing."))
