// Which plugin code a thread of qdrun's process is running. The guards for fatal signals and exit()
// in qdrun's own process (core/app/run_guard.cpp) name the component and call from it.
#pragma once

#include <string>

namespace qd::runtime {

struct PluginCall {
  const char* who = nullptr;   // the component's label: "mutator 'iso' (/path/qd_basic.so)"
  const char* call = nullptr;  // "mutate()"
  bool own = false;            // the calling thread's own call, not the run thread's
};

// The calling thread's innermost plugin call; else the run thread's, since plugin code may run
// threads of its own (the autoencoder's OpenMP training); else {nullptr, nullptr}. Reads only
// plain memory: safe in a signal handler.
PluginCall current_plugin_call() noexcept;

// Makes the calling thread the run thread (the one that drives the loop): its calls are the
// fallback for threads that have none.
void mark_run_thread() noexcept;

// Marks the calling thread as inside `call` of `who` for its lifetime. `who` must outlive it.
class PluginCallScope {
 public:
  PluginCallScope(const std::string& who, const char* call) noexcept;
  ~PluginCallScope();
  PluginCallScope(const PluginCallScope&) = delete;
  PluginCallScope& operator=(const PluginCallScope&) = delete;

 private:
  PluginCall previous_;
};

}  // namespace qd::runtime
