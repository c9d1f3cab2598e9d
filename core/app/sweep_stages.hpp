// The stages of a sweep (sweep.hpp), one file each: plan (sweep_plan.cpp: every run resolved,
// built and its directory checked before any starts), estimate (sweep_estimate.cpp: --dry-run's
// cost), execute (sweep.cpp: child qdruns started, watched and stopped).
#pragma once

#include "sweep.hpp"

#include "runtime/experiment.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace qd::app {

// A run directory's file as text ("" when missing or unreadable: for the sweep's own lines).
std::string read_text(const std::filesystem::path& p);

enum class Action { kFresh, kRestart, kResume, kSkip };

struct PlannedRun {
  std::string label;  // <name>/seed-<seed>
  std::filesystem::path dir;
  Action action = Action::kFresh;
  std::string why;                 // for the start/skip line
  std::vector<std::string> child;  // qdrun arguments (without the executable and --workers)
  std::string file;                // the experiment file, and the overrides the run gets
  std::vector<std::string> overrides;
  const std::uint64_t* seed = nullptr;
  int first_loop = 0;    // the loop a resumed run starts at
  std::string resolved;  // the configuration planned (resolved_toml), checked again at its start
};

// One registry per [plugins] path list, set up as qdrun does for one experiment.
class RegistryCache {
 public:
  explicit RegistryCache(const std::function<void(runtime::Registry&, const std::vector<std::string>&)>& setup)
      : setup_(setup) {}
  const runtime::Registry& get(const std::vector<std::string>& from_file) {
    std::string key;
    for (const auto& p : from_file) key += p + '\n';
    auto& slot = cache_[key];
    if (!slot) {
      slot = std::make_unique<runtime::Registry>();
      setup_(*slot, from_file);
    }
    return *slot;
  }

 private:
  const std::function<void(runtime::Registry&, const std::vector<std::string>&)>& setup_;
  std::map<std::string, std::unique_ptr<runtime::Registry>> cache_;
};

// The experiment file with the run's overrides, seed and output directory applied.
runtime::Document read_run_document(const SweepOptions& o, const std::string& file, const std::uint64_t* seed,
                                    const std::vector<std::string>& overrides);

// Plans and checks every run (each file that no other includes, times each seed): what it will do
// with its directory, and the child's arguments. Throws qd::InputError for anything wrong.
std::vector<PlannedRun> plan_sweep(const SweepOptions& o, RegistryCache& regs);

// A run starts with the configuration the sweep planned and checked, or not at all: its experiment
// file (or one it includes) edited while the sweep runs, a sweep of hours, would otherwise give
// runs of two configurations under one name without a word. Checked before the run starts (which
// names the difference); the child checks it once more when it has read the file
// (--planned-config), which closes the window between the two.
void check_unchanged(const SweepOptions& o, const PlannedRun& r, RegistryCache& regs);

// --dry-run's estimate: per run and in total, in core-hours, and the sweep's wall time on this
// machine. Pilots run loop 0 of each distinct environment setup once (the first seed's).
void print_cost_estimate(const SweepOptions& o, const std::vector<PlannedRun>& runs,
                         const std::vector<std::size_t>& pending, RegistryCache& regs, int concurrent, int workers,
                         int hw);

}  // namespace qd::app
