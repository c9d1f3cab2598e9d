// Reports a PluginInfo size that is not the host's (built against other headers).
#include <qd/plugin.hpp>
namespace {
const qd::PluginInfo* entry() {
  static const qd::PluginInfo info{
      qd::kPluginAbiVersion, sizeof(qd::PluginInfo) + 8, QD_BUILD_FINGERPRINT, "bad_size", "1", 0, nullptr};
  return &info;
}
}  // namespace
BOOST_DLL_ALIAS(entry, qd_plugin_entry_v1)
