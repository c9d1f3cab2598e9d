// Claims ABI version 999: the host must refuse it before reading anything else.
#include <qd/plugin.hpp>
namespace {
const qd::PluginInfo* entry() {
  static const qd::PluginInfo info{999u, sizeof(qd::PluginInfo), QD_BUILD_FINGERPRINT, "bad_abi", "1", 0, nullptr};
  return &info;
}
}  // namespace
BOOST_DLL_ALIAS(entry, qd_plugin_entry_v1)
