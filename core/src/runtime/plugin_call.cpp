#include "runtime/plugin_call.hpp"

#include <atomic>

namespace qd::runtime {
namespace {

// initial-exec: the variables live in the executable's static TLS block, so reading them from a
// signal handler never allocates.
thread_local PluginCall t_call __attribute__((tls_model("initial-exec")));
thread_local bool t_run_thread __attribute__((tls_model("initial-exec"))) = false;
// The run thread's current call, for other threads (a handler may read it while it changes: at
// worst it names the previous call).
std::atomic<const char*> g_who{nullptr}, g_call{nullptr};

void publish(const PluginCall& c) noexcept {
  if (!t_run_thread) return;
  g_call.store(c.call, std::memory_order_relaxed);
  g_who.store(c.who, std::memory_order_relaxed);
}

}  // namespace

PluginCall current_plugin_call() noexcept {
  if (t_call.who) return PluginCall{t_call.who, t_call.call, true};
  return PluginCall{g_who.load(std::memory_order_relaxed), g_call.load(std::memory_order_relaxed), false};
}

void mark_run_thread() noexcept {
  t_run_thread = true;
}

PluginCallScope::PluginCallScope(const std::string& who, const char* call) noexcept : previous_(t_call) {
  t_call = PluginCall{who.c_str(), call};
  publish(t_call);
}

PluginCallScope::~PluginCallScope() {
  t_call = previous_;
  publish(t_call);
}

}  // namespace qd::runtime
