// Built "with another compiler": its fingerprint differs from the core's.
#include <qd/plugin.hpp>
namespace {
const qd::PluginInfo* entry() {
  static const qd::PluginInfo info{qd::kPluginAbiVersion,
                                   sizeof(qd::PluginInfo),
                                   "gcc-1.0;cxx11abi=0;eigen=2.0",
                                   "bad_fingerprint",
                                   "1",
                                   0,
                                   nullptr};
  return &info;
}
}  // namespace
BOOST_DLL_ALIAS(entry, qd_plugin_entry_v1)
