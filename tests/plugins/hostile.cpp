// Hostile libraries on the plugin search path (issue 32, case 12): each is built from this file with
// one HOSTILE_* definition and must be rejected by name, never take qdrun (or --list) down with it,
// and never be loaded by a run that does not use it.
//  * HOSTILE_CTOR_EXIT: a static constructor calls exit(0);
//  * HOSTILE_CTOR_SEGV: a static constructor crashes (SIGSEGV);
//  * HOSTILE_CTOR_HANG: a static constructor never returns;
//  * HOSTILE_NULL_ENTRY: the entry symbol exists but holds a null pointer;
//  * HOSTILE_BAD_COMPONENTS: the plugin information passes the version checks but its component
//    list points nowhere;
//  * none: a well-formed plugin (HOSTILE_NAME) whose mutator "misspelt" reads a parameter it never
//    declared (its code says "sigmaa", its declaration "sigma").
#include <qd/plugin.hpp>

#include <unistd.h>
#include <csignal>
#include <cstdlib>

#ifndef HOSTILE_NAME
#define HOSTILE_NAME "misspelt"
#endif

namespace {

#if defined(HOSTILE_CTOR_EXIT)
struct ExitAtLoad {
  ExitAtLoad() { std::exit(0); }
} exit_at_load;
#elif defined(HOSTILE_CTOR_SEGV)
struct CrashAtLoad {
  CrashAtLoad() { std::raise(SIGSEGV); }
} crash_at_load;
#elif defined(HOSTILE_CTOR_HANG)
struct HangAtLoad {
  HangAtLoad() {
    for (;;) ::pause();
  }
} hang_at_load;
#endif

constexpr qd::ParamSpec kParams[] = {qd::param_float("sigma", "0.1", 0.0, 10.0, "step size")};

class Misspelt final : public qd::Mutator {
 public:
  Misspelt(const qd::Config& c, const qd::BuildContext&) : sigma_(c.get_float("sigmaa")) {}
  void mutate(const qd::Parents& p, std::size_t, qd::MutateContext&, qd::Offspring& out) override {
    out.theta = p.theta * (1.0 + sigma_);
  }

 private:
  double sigma_;
};

}  // namespace

#if defined(HOSTILE_NULL_ENTRY)
extern "C" {
__attribute__((visibility("default"))) const void* qd_plugin_entry_v1 = nullptr;
}
#elif defined(HOSTILE_BAD_COMPONENTS)
namespace {
const qd::PluginInfo* bad_components() {
  static const qd::PluginInfo info{qd::kPluginAbiVersion,
                                   static_cast<std::uint32_t>(sizeof(qd::PluginInfo)),
                                   QD_BUILD_FINGERPRINT,
                                   HOSTILE_NAME,
                                   "0.0.1",
                                   3,
                                   reinterpret_cast<const qd::ComponentInfo*>(std::uintptr_t{16})};
  return &info;
}
}  // namespace
BOOST_DLL_ALIAS(bad_components, qd_plugin_entry_v1)
#else
QD_PLUGIN(HOSTILE_NAME, "0.0.1",
          qd::component<Misspelt>(qd::Kind::kMutator, HOSTILE_NAME, "reads a parameter it does not declare", kParams))
#endif
