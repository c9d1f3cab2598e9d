// Sweeps, stage 1: the plan (sweep_stages.hpp). Every run of the sweep resolved and built as
// qdrun would, its run directory read (fresh, restart, resume or skip), before any run starts.
#include "sweep_stages.hpp"

#include "runtime/checkpoint.hpp"
#include "runtime/components.hpp"
#include "runtime/number_text.hpp"
#include "runtime/run_directory.hpp"
#include "runtime/run_files.hpp"

#include <qd/errors.hpp>

#include <algorithm>
#include <charconv>
#include <cstdio>
#include <fstream>
#include <set>
#include <sstream>

namespace qd::app {
namespace fs = std::filesystem;
using runtime::Document;
using runtime::Registry;

std::string read_text(const fs::path& p) {
  try {
    return runtime::read_run_file(p, std::uint64_t{1} << 30);
  } catch (const std::exception&) {
    return "";
  }
}

Document read_run_document(const SweepOptions& o, const std::string& file, const std::uint64_t* seed,
                           const std::vector<std::string>& overrides) {
  Document doc = Document::read(file);
  for (const auto& s : overrides) doc.apply_override(s);
  if (seed) doc.set_integer("experiment.seed", static_cast<std::int64_t>(*seed));
  if (!o.output.empty()) doc.set_string("output.dir", o.output);
  return doc;
}

namespace {

// The first key whose value differs between two resolved configurations (whatever the order of
// their tables), for the message about a run directory that holds another run (or a file changed
// since the plan: `then` instead of "there").
std::string first_difference(const std::string& a, const std::string& b, const char* then = "there") {
  const std::vector<runtime::ConfigDifference> d = runtime::config_differences(a, b);
  if (d.empty()) return "";
  return "'" + d[0].key + " = " + d[0].before + "' " + then + ", '" + d[0].key + " = " + d[0].after + "' now";
}

// Whether `key` (table.name) names a parameter the run accepts: core tables always, component
// tables when the chosen component declares it.
bool accepts(const runtime::Experiment& ex, const std::string& key) {
  const std::string table = key.substr(0, key.find('.'));
  const std::string name = key.find('.') == std::string::npos ? "" : key.substr(key.find('.') + 1);
  for (const auto& t : runtime::core_tables())
    if (table == t.name) return true;
  for (const runtime::ComponentConfig* cc :
       {&ex.environment, &ex.descriptor, &ex.representation, &ex.mutator, &ex.initial}) {
    if (cc->table != table || !cc->entry || cc->implied) continue;
    const ComponentInfo& info = *cc->entry->info;
    for (std::uint32_t k = 0; k < info.param_count; ++k)
      if (name == info.params[k].key) return true;
  }
  return false;
}

// Builds the run as qdrun would (every component constructed, nothing written): the full check of
// an experiment. Returns the resolved settings and configuration.
struct Checked {
  runtime::ExperimentSettings settings;
  std::string resolved_toml;
  fs::path dir;
};

Checked check(const Document& doc, const Registry& reg) {
  runtime::Experiment ex = runtime::resolve(doc, reg);
  runtime::build_components(ex, reg);  // every factory and cross-check; nothing is written
  const auto& s = ex.settings;
  return {s, ex.resolved_toml, fs::path(s.output_dir) / s.name / ("seed-" + std::to_string(s.seed))};
}

// Loops metrics.csv shows complete (loop 0's single row, or a loop's last iteration): where a
// resumed run will start, give or take the checkpoint it returns to.
int completed_loops(const fs::path& metrics, int iterations) {
  std::istringstream in(read_text(metrics));
  std::string line;
  int done = 0;
  std::getline(in, line);  // header: loop,iteration,...
  while (std::getline(in, line)) {
    int loop = -1, it = -1;
    if (std::sscanf(line.c_str(), "%d,%d", &loop, &it) != 2) continue;
    if (loop == 0 || it == iterations - 1) done = std::max(done, loop + 1);
  }
  return done;
}

// The configuration a run of `file` gets, as the child qdrun resolves it (components not built):
// what the sweep planned, checked again when the run starts (here, and by the child itself).
std::string run_configuration(const SweepOptions& o, const std::string& file, const std::uint64_t* seed,
                              const std::vector<std::string>& overrides, RegistryCache& regs) {
  const Document doc = read_run_document(o, file, seed, overrides);
  return runtime::resolve(doc, regs.get(doc.plugin_paths())).resolved_toml;
}

PlannedRun plan_one(const SweepOptions& o, const std::string& file, const std::uint64_t* seed, RegistryCache& regs) {
  std::vector<std::string> overrides = o.sets;
  auto read = [&](const std::vector<std::string>& extra) { return read_run_document(o, file, seed, extra); };
  Document doc = read(overrides);
  const Registry& reg = regs.get(doc.plugin_paths());
  runtime::Experiment ex = runtime::resolve(doc, reg);
  bool changed = false;
  for (const auto& s : o.optional_sets)
    if (accepts(ex, s.substr(0, s.find('=')))) {
      overrides.push_back(s);
      changed = true;
    }
  if (o.evaluations >= 0) {
    // Loop 0 takes initial_samples evaluations, every later loop iterations x batch.
    const auto& st = ex.settings;
    const long long per_loop = static_cast<long long>(st.iterations) * st.batch;
    const long long rest = std::max(0LL, o.evaluations - st.initial_samples);
    overrides.push_back("experiment.loops=" + std::to_string(1 + (rest + per_loop - 1) / per_loop));
    changed = true;
  }
  if (changed) doc = read(overrides);
  const Checked now = check(doc, reg);

  PlannedRun p;
  p.file = file;
  p.overrides = overrides;
  p.seed = seed;
  p.dir = now.dir;
  p.label = now.settings.name + "/seed-" + std::to_string(now.settings.seed);
  p.resolved = run_configuration(o, file, seed, overrides, regs);
  p.child.push_back(file);
  p.child.insert(p.child.end(), {"--planned-config", planned_config_tag(p.resolved)});
  if (seed) p.child.insert(p.child.end(), {"--seed", std::to_string(*seed)});
  if (!o.output.empty()) p.child.insert(p.child.end(), {"--output", o.output});
  for (const auto& s : overrides) p.child.insert(p.child.end(), {"--set", s});

  const std::string holder = runtime::RunDirectory::holder(p.dir);
  if (!holder.empty()) throw InputError(p.dir.string() + " is in use by qdrun " + holder + "; wait for it or stop it");
  // What the run will read and append to is checked now, before any run starts: a FIFO there
  // would block it, a symlink lead out of the directory.
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(p.dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name == "qdrun.log" || name == "status" || name == "config.toml" || name == "checkpoint.bin" ||
        name == "dataset.bin" || name == "metrics.csv" || name == "training.csv" ||
        name.rfind("archive-state-", 0) == 0)
      runtime::require_regular_or_absent(e.path());
  }
  const bool has_checkpoint = runtime::CheckpointStore::exists(p.dir);
  const bool has_archive = runtime::exists_nofollow(p.dir / "archive.csv");
  const std::string status = runtime::RunDirectory::read_status(p.dir);
  std::string found;
  const runtime::Leftover leftover =
      has_checkpoint ? runtime::Leftover::kUnfinishedStart : runtime::RunDirectory::leftover(p.dir, &found);
  if (leftover == runtime::Leftover::kNone) {
    p.action = Action::kFresh;
    p.why = "fresh";
    return p;
  }
  if (leftover == runtime::Leftover::kResults)
    // Anything without a checkpoint but a run that died in loop 0 (a finished run copied without
    // its *.bin files, checkpoint.bin deleted, a directory of another kind) holds results a
    // restart would destroy.
    throw InputError(p.dir.string() + " holds results but no checkpoint (" + found +
                     "; copied without its *.bin files?); the sweep will not touch it: move it away or choose "
                     "another --output");
  // The directory holds this run (only the budget and output keys may differ), or the start of it.
  Document old = Document::read(p.dir / "config.toml");
  const Registry& old_reg = regs.get(old.plugin_paths());
  const int old_loops = runtime::resolve(old, old_reg).settings.loops;
  old.set_integer("experiment.loops", now.settings.loops);
  old.set_integer("evaluation.workers", now.settings.workers);
  old.set_integer("output.snapshot_every", now.settings.snapshot_every);
  old.set_string("output.dir", now.settings.output_dir);
  const Checked then = check(old, old_reg);
  // Compared key by key: config.toml lists the environment's default descriptor among the tables
  // (it is explicit there), a fresh resolve after them.
  if (const std::string d = first_difference(then.resolved_toml, now.resolved_toml); !d.empty())
    throw InputError(p.dir.string() + " holds a run of another configuration than " + file + " (" + d +
                     "); move it away or choose another --output");
  if (!has_checkpoint) {
    p.action = Action::kRestart;
    p.why = "restart: it died before its first checkpoint";
    return p;
  }
  const bool complete = status.rfind("complete", 0) == 0 && has_archive;
  p.child = {"--resume", p.dir.string(), "--set", "experiment.loops=" + std::to_string(now.settings.loops)};
  if (complete && old_loops >= now.settings.loops) {
    p.action = Action::kSkip;
    p.why = "complete, " + std::to_string(old_loops) + " loops";
  } else if (complete) {
    p.action = Action::kResume;
    p.first_loop = old_loops;
    p.why = "resume: extend " + std::to_string(old_loops) + " to " + std::to_string(now.settings.loops) + " loops";
  } else {
    p.first_loop = completed_loops(p.dir / "metrics.csv", now.settings.iterations);
    p.action = Action::kResume;
    std::string s = status.substr(0, status.find('\n'));
    p.why = "resume: was '" + s + "'";
  }
  return p;
}

// Files that other files of the sweep include (`include = "base.toml"` or a list): shared settings,
// not experiments, so `qdrun experiments/striker/*.toml` runs the algorithm files only.
std::set<std::string> included_files(const std::vector<std::string>& files) {
  std::set<std::string> out;
  for (const auto& f : files) {
    std::ifstream in(f);
    std::string line;
    while (std::getline(in, line)) {
      const std::size_t start = line.find_first_not_of(" \t");
      if (start == std::string::npos || line.compare(start, 7, "include") != 0) continue;
      const std::size_t eq = line.find('=', start);
      if (eq == std::string::npos || line.find_first_not_of(" \t", start + 7) != eq) continue;
      for (std::size_t q = line.find('"', eq); q != std::string::npos; q = line.find('"', q)) {
        const std::size_t e = line.find('"', q + 1);
        if (e == std::string::npos) break;
        std::error_code ec;
        out.insert(fs::weakly_canonical(fs::path(f).parent_path() / line.substr(q + 1, e - q - 1), ec).string());
        q = e + 1;
      }
    }
  }
  return out;
}

}  // namespace

void check_unchanged(const SweepOptions& o, const PlannedRun& r, RegistryCache& regs) {
  const std::string now = run_configuration(o, r.file, r.seed, r.overrides, regs);
  if (now != r.resolved)
    throw InputError(r.file + " (or a file it includes) changed since the sweep planned this run (" +
                     first_difference(r.resolved, now, "then") + "); run the sweep again to plan with it");
}

std::vector<PlannedRun> plan_sweep(const SweepOptions& o, RegistryCache& regs) {
  std::vector<PlannedRun> runs;
  std::map<std::string, std::string> owner;  // run directory -> label of the file that made it
  const std::set<std::string> included = included_files(o.experiments);
  for (const auto& file : o.experiments) {
    std::error_code ec;
    if (included.count(fs::weakly_canonical(file, ec).string())) {
      std::printf("sweep: %s is included by the other files, not an experiment: skipped\n", file.c_str());
      continue;
    }
    std::vector<const std::uint64_t*> seeds;
    for (const auto& s : o.seeds) seeds.push_back(&s);
    if (seeds.empty()) seeds.push_back(nullptr);
    for (const auto* seed : seeds) {
      PlannedRun p = plan_one(o, file, seed, regs);
      const std::string key = fs::weakly_canonical(p.dir).string();
      if (owner.count(key))
        throw InputError(file + ": run directory " + p.dir.string() + " is also the one of " + owner[key] +
                         " (two experiments with the same experiment.name?)");
      owner[key] = file + " (" + p.label + ")";
      runs.push_back(std::move(p));
    }
  }

  return runs;
}

std::string planned_config_tag(const std::string& resolved_toml) {
  char tag[16];
  std::snprintf(tag, sizeof(tag), "%08x", runtime::crc32c(resolved_toml.data(), resolved_toml.size()));
  return tag;
}

std::vector<std::uint64_t> parse_seed_list(const std::string& text) {
  constexpr std::uint64_t kMaxSeed = 9000000000000000;  // experiment.seed's range
  constexpr std::uint64_t kMaxRange = 100000;
  std::vector<std::uint64_t> out;
  std::stringstream ss(text);
  std::string part;
  auto number = [&](const std::string& s, const std::string& in) {
    std::uint64_t v = 0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (s.empty() || end != s.data() + s.size() || (ec != std::errc() && ec != std::errc::result_out_of_range))
      throw InputError("--seeds " + text + ": '" + in +
                       "' is not a non-negative integer or a range (use 100,200,300 or 1-5)");
    if (ec == std::errc::result_out_of_range || v > kMaxSeed)
      throw InputError("--seeds " + text + ": seed " + s + " is out of range [0, " + std::to_string(kMaxSeed) + "]");
    return v;
  };
  while (std::getline(ss, part, ',')) {
    const std::size_t dash = part.find('-', 1);
    if (dash == std::string::npos) {
      out.push_back(number(part, part));
      continue;
    }
    const std::uint64_t a = number(part.substr(0, dash), part), b = number(part.substr(dash + 1), part);
    if (b < a)
      throw InputError("--seeds " + text + ": the range '" + part + "' goes down (write it " + std::to_string(b) + "-" +
                       std::to_string(a) + ")");
    if (b - a >= kMaxRange)
      throw InputError("--seeds " + text + ": the range '" + part + "' holds " + std::to_string(b - a + 1) +
                       " seeds, more than the " + std::to_string(kMaxRange) + " a sweep takes");
    for (std::uint64_t s = a; s <= b; ++s) out.push_back(s);
  }
  if (out.empty()) throw InputError("--seeds: empty list");
  std::set<std::uint64_t> seen;
  for (auto s : out)
    if (!seen.insert(s).second) throw InputError("--seeds " + text + ": seed " + std::to_string(s) + " twice");
  return out;
}

}  // namespace qd::app
