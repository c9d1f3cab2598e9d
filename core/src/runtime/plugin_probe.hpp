// Reading a plugin library in a process of its own (discovery): a library whose constructors or
// entry function crash, exit or hang is named and left out instead of taking qdrun down.
#pragma once

#include "runtime/registry.hpp"

#include <sys/types.h>

#include <chrono>
#include <deque>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace qd::runtime {

// What a probe read: a plugin's declarations, owning every string and array they point to.
struct ProbeCopy {
  std::deque<std::string> strings;
  std::deque<std::vector<ParamSpec>> params;
  std::vector<ComponentInfo> components;
  PluginInfo info{};
};

struct Probe {
  std::filesystem::path path;
  pid_t pid = -1;
  int fd = -1;
  std::string message;
  bool timed_out = false;
  int status = 0;
  std::chrono::steady_clock::time_point deadline;
};

// Starts a probe process for `path`; throws SystemError when none can be started.
Probe start_probe(const std::filesystem::path& path);
// Collects a probe's message until it ends or its deadline passes (then it is killed).
void finish_probe(Probe& p);
// The probe's verdict: the plugin's declarations, or PluginError (its rejection, or how the probe
// process ended: a crash, exit() or a hang in the library's constructors or entry function).
std::shared_ptr<ProbeCopy> verdict(const Probe& p, Rejection& seen);

}  // namespace qd::runtime
