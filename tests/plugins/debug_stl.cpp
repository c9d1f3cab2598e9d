// An ordinary plugin compiled with -D_GLIBCXX_DEBUG (see CMakeLists.txt): its standard containers
// have another layout than the core's, so the host must refuse it before using anything in it.
#include <qd/plugin.hpp>

namespace {
class Nothing final : public qd::Mutator {
 public:
  Nothing(const qd::Config&, const qd::BuildContext&) {}
  void mutate(const qd::Parents&, std::size_t, qd::MutateContext&, qd::Offspring&) override {}
};
}  // namespace

QD_PLUGIN("debug_stl", "1", qd::component<Nothing>(qd::Kind::kMutator, "debug-stl-nothing", "Does nothing."))
