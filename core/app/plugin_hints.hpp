// Hints about plugins for a run directory: which library a run used when a component cannot be
// found now, and whether the plugins found now are the ones the run was made with.
#pragma once

#include "runtime/experiment.hpp"
#include "runtime/registry.hpp"

#include <qd/errors.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace qd::runtime {
class Run;
}

namespace qd::app {

// For a run directory whose components cannot all be found: one sentence per component that its
// provenance files record but `registry` does not provide (which library, where it was, and whether
// that file is gone, rejected or outside the search path). Empty when there is nothing to say.
std::string missing_plugin_hint(const std::filesystem::path& run_dir, const runtime::Registry& registry);

// For --resume, --replay and --latents: the components of `ex` (built) that would now come from
// another plugin than the one the run's newest session recorded, which happens when the library the
// run used is gone and another provides the same name (one sentence each; "" when none). A plugin
// of the same name at another path is the same plugin; one whose version changed adds a sentence to
// `notes`.
std::string changed_plugins(const std::filesystem::path& run_dir, const runtime::Experiment& ex,
                            std::vector<std::string>* notes = nullptr);

// A run continues (or is replayed) with the plugins it was made with: when the library it used is
// gone and another one provides the same component name, that is an error naming both, not a
// silent switch. Version changes are printed as notes unless `quiet`.
void check_same_plugins(bool quiet, const runtime::Run& run);

// Runs `build` (resolving a run directory's configuration and building its components); when a
// component cannot be found, the error also says which library the run used and where it was.
template <class F>
auto with_plugin_hint(const std::filesystem::path& dir, const runtime::Registry& reg, F&& build) -> decltype(build()) {
  try {
    return build();
  } catch (const InputError& e) {
    const std::string hint = missing_plugin_hint(dir, reg);
    if (hint.empty()) throw;
    std::string msg = e.what();
    const auto first_line_end = msg.find('\n');
    msg.insert(first_line_end == std::string::npos ? msg.size() : first_line_end, "; " + hint);
    throw InputError(msg);
  }
}

}  // namespace qd::app
