#include "sweep.hpp"

#include "run_guard.hpp"
#include "runtime/checkpoint.hpp"
#include "runtime/clock.hpp"
#include "runtime/components.hpp"
#include "runtime/cost_estimate.hpp"
#include "runtime/evaluator.hpp"
#include "runtime/experiment.hpp"
#include "runtime/run.hpp"
#include "runtime/run_directory.hpp"
#include "runtime/run_files.hpp"

#include <qd/errors.hpp>

#include <toml++/toml.h>

#include <fcntl.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <sstream>

namespace qd::app {
namespace fs = std::filesystem;
using runtime::Document;
using runtime::Registry;

namespace {

using runtime::toml_string;

// A run directory's file as text ("" when missing or unreadable: for the sweep's own lines).
std::string read_text(const fs::path& p) {
  try {
    return runtime::read_run_file(p, std::uint64_t{1} << 30);
  } catch (const std::exception&) {
    return "";
  }
}

std::string last_line(const fs::path& p) {
  std::istringstream in(read_text(p));
  std::string line, last;
  while (std::getline(in, line))
    if (!line.empty()) last = line;
  return last;
}

// First line where two texts differ, for the message about a run directory that holds another run
// (or a file changed since the plan: `then` instead of "there").
std::string first_difference(const std::string& a, const std::string& b, const char* then = "there") {
  std::istringstream ia(a), ib(b);
  std::string la, lb;
  while (true) {
    const bool ga = static_cast<bool>(std::getline(ia, la)), gb = static_cast<bool>(std::getline(ib, lb));
    if (!ga && !gb) return "";
    if (!ga) la = "<end>";
    if (!gb) lb = "<end>";
    if (la != lb) return "'" + la + "' " + then + ", '" + lb + "' now";
  }
}

// The resolved configuration with its tables in sorted order: a run directory's config.toml lists
// the environment's default descriptor among the tables, a fresh resolve appends it at the end.
std::string canonical(const std::string& toml) {
  std::vector<std::string> blocks(1);
  std::istringstream in(toml);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    if (line[0] == '[' && !blocks.back().empty()) blocks.emplace_back();
    blocks.back() += line + "\n";
  }
  std::sort(blocks.begin(), blocks.end());
  std::string out;
  for (const auto& b : blocks) out += b;
  return out;
}

enum class Action { kFresh, kRestart, kResume, kSkip };

struct PlannedRun {
  std::string label;  // <name>/seed-<seed>
  fs::path dir;
  Action action = Action::kFresh;
  std::string why;                 // for the start/skip line
  std::vector<std::string> child;  // qdrun arguments (without the executable and --workers)
  std::string file;                // the experiment file, and the overrides the run gets
  std::vector<std::string> overrides;
  const std::uint64_t* seed = nullptr;
  int first_loop = 0;    // the loop a resumed run starts at
  std::string resolved;  // the configuration planned (canonical), checked again at its start
};

class RegistryCache {
 public:
  explicit RegistryCache(const std::function<void(Registry&, const std::vector<std::string>&)>& setup)
      : setup_(setup) {}
  const Registry& get(const std::vector<std::string>& from_file) {
    std::string key;
    for (const auto& p : from_file) key += p + '\n';
    auto& slot = cache_[key];
    if (!slot) {
      slot = std::make_unique<Registry>();
      setup_(*slot, from_file);
    }
    return *slot;
  }

 private:
  const std::function<void(Registry&, const std::vector<std::string>&)>& setup_;
  std::map<std::string, std::unique_ptr<Registry>> cache_;
};

// Whether `key` (table.name) names a parameter the run accepts: core tables always, component
// tables when the chosen component declares it.
bool accepts(const runtime::Experiment& ex, const std::string& key) {
  const std::string table = key.substr(0, key.find('.'));
  const std::string name = key.find('.') == std::string::npos ? "" : key.substr(key.find('.') + 1);
  for (const auto& t : runtime::core_tables())
    if (table == t.name) return true;
  for (const runtime::ComponentConfig* cc :
       {&ex.environment, &ex.descriptor, &ex.representation, &ex.mutator, &ex.initial}) {
    if (cc->table != table || !cc->entry) continue;
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
  return {s, canonical(ex.resolved_toml), fs::path(s.output_dir) / s.name / ("seed-" + std::to_string(s.seed))};
}

// The experiment file with the run's overrides, seed and output directory applied.
Document read_run_document(const SweepOptions& o, const std::string& file, const std::uint64_t* seed,
                           const std::vector<std::string>& overrides) {
  Document doc = Document::read(file);
  for (const auto& s : overrides) doc.apply_override(s);
  if (seed) doc.apply_override("experiment.seed=" + std::to_string(*seed));
  if (!o.output.empty()) doc.apply_override("output.dir=" + toml_string(o.output));
  return doc;
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

// A run starts with the configuration the sweep planned and checked, or not at all: its experiment
// file (or one it includes) edited while the sweep runs, a sweep of hours, would otherwise give
// runs of two configurations under one name without a word. Checked before the run starts (which
// names the difference); the child checks it once more when it has read the file
// (--planned-config), which closes the window between the two.
void check_unchanged(const SweepOptions& o, const PlannedRun& r, RegistryCache& regs) {
  const std::string now = run_configuration(o, r.file, r.seed, r.overrides, regs);
  if (now != r.resolved)
    throw InputError(r.file + " (or a file it includes) changed since the sweep planned this run (" +
                     first_difference(canonical(r.resolved), canonical(now), "then") +
                     "); run the sweep again to plan with it");
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
  old.apply_override("experiment.loops=" + std::to_string(now.settings.loops));
  old.apply_override("evaluation.workers=" + std::to_string(now.settings.workers));
  old.apply_override("output.snapshot_every=" + std::to_string(now.settings.snapshot_every));
  old.apply_override("output.dir=" + toml_string(now.settings.output_dir));
  const Checked then = check(old, old_reg);
  if (then.resolved_toml != now.resolved_toml)
    throw InputError(p.dir.string() + " holds a run of another configuration than " + file + " (" +
                     first_difference(then.resolved_toml, now.resolved_toml) +
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

// A sweep stopped by a stop signal (SIGINT, SIGTERM, SIGHUP, SIGUSR1, ...: those a run handles as
// SIGTERM, run_guard.hpp) passes it on to its runs, so each stops as qdrun does alone (its status
// says where, --resume continues), waits for them and says so; no new run starts. A signal the
// sweep was started with ignored (nohup) stays ignored, for the runs too. Runs are tracked where
// the handler can read them (async-signal-safe). SIGPIPE is ignored.
constexpr std::size_t kMaxChildren = 4096;  // --jobs at most
std::atomic<pid_t> g_children[kMaxChildren];
volatile std::sig_atomic_t g_stop_signal = 0;
std::vector<int> g_forwarded;  // the signals the sweep forwards (set before any child starts)

void track_child(pid_t pid, bool running) {
  for (auto& c : g_children) {
    pid_t expected = running ? 0 : pid;
    if (c.compare_exchange_strong(expected, running ? pid : 0)) return;
  }
}

void on_sweep_stop(int sig) {
  g_stop_signal = sig;
  for (const auto& c : g_children)
    if (const pid_t pid = c.load(); pid > 0) ::kill(pid, sig);
}

struct StopForwarding {
  StopForwarding() {
    // A reader of the sweep's lines that goes away (qdrun ... | head) takes the lines, not the runs:
    // qdrun reports the lost output when the sweep ends (exit 4).
    if (struct sigaction now; ::sigaction(SIGPIPE, nullptr, &now) == 0 && now.sa_handler == SIG_DFL)
      ::signal(SIGPIPE, SIG_IGN);
    struct sigaction sa;
    std::memset(&sa, 0, sizeof(sa));
    sa.sa_handler = on_sweep_stop;
    sigemptyset(&sa.sa_mask);
    for (const int sig : stop_signals()) {
      struct sigaction now;
      if (::sigaction(sig, nullptr, &now) != 0 || (now.sa_flags & SA_SIGINFO) || now.sa_handler != SIG_DFL) continue;
      g_forwarded.push_back(sig);
      ::sigaction(sig, &sa, nullptr);
    }
  }
};

// Starts one child qdrun with its output appended to RUN_DIR/qdrun.log. The child gets SIGKILL
// when the sweep dies, so an interrupted sweep leaves no orphan runs writing into directories.
pid_t start_child(const std::string& exe, const std::vector<std::string>& args, const fs::path& log) {
  std::vector<char*> argv;
  argv.push_back(const_cast<char*>(exe.c_str()));
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  // Opened here, with the checks of every run directory file (a FIFO there would block the child,
  // a symlink or hard link send its output elsewhere): an error names it before anything starts.
  const int fd = runtime::open_for_update(log, O_APPEND, true);
  const pid_t parent = ::getpid();
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(fd);
    throw SystemError(std::string("cannot start a run: fork failed: ") + std::strerror(errno));
  }
  if (pid == 0) {
    for (const int sig : g_forwarded) ::signal(sig, SIG_DFL);  // not the sweep's forwarding; ignored ones stay so
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(127);  // the sweep died before prctl took effect
    ::dup2(fd, STDOUT_FILENO);
    ::dup2(fd, STDERR_FILENO);
    ::execv(exe.c_str(), argv.data());
    std::fprintf(stderr, "qdrun sweep: cannot execute %s: %s\n", exe.c_str(), std::strerror(errno));
    ::_exit(127);
  }
  ::close(fd);
  return pid;
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

// The tables a loop-0 pilot depends on: runs that share them share the pilot's episode costs.
std::string pilot_key(const std::string& resolved_toml) {
  std::string key;
  std::istringstream in(canonical(resolved_toml));
  std::string line, table;
  while (std::getline(in, line)) {
    if (!line.empty() && line[0] == '[') table = line;
    if (table == "[environment]" || table == "[descriptor]" || table == "[initial]" || table == "[policy]" ||
        (table == "[experiment]" && line.rfind("initial_samples", 0) == 0))
      key += line + "\n";
  }
  return key;
}

std::string hours(double seconds) {
  char buf[32];
  std::snprintf(buf, sizeof buf, seconds < 36 ? "%.3f" : "%.2f", seconds / 3600.0);
  return buf;
}

// What a resumed run's completed loops cost it per evaluation, in core-seconds: its metrics.csv
// (wall time, training out) times the workers of the session that ran the loop measured.
struct MeasuredCost {
  double core_seconds_per_evaluation = 0.0;  // 0: nothing to go on
  int loop = -1;
  int workers = 1;
};

MeasuredCost measured_cost(const fs::path& dir, int iterations) {
  std::istringstream metrics(read_text(dir / "metrics.csv"));
  const runtime::MeasuredRate rate = runtime::measured_rate(metrics, iterations);
  MeasuredCost out;
  if (rate.loop < 1) return out;
  try {
    const fs::path path = runtime::session_provenance(dir, rate.loop);
    const toml::table provenance = toml::parse(read_text(path), path.string());
    out.workers = std::max<int>(1, provenance["workers"].value_or(1));
  } catch (const toml::parse_error&) {
    // Unreadable provenance: one worker, the sweep's default.
  }
  out.loop = rate.loop;
  out.core_seconds_per_evaluation = rate.seconds_per_evaluation * out.workers;
  return out;
}

// --dry-run's estimate: per run and in total, in core-hours, and the sweep's wall time on this
// machine. Pilots run loop 0 of each distinct environment setup once (the first seed's).
void print_cost_estimate(const SweepOptions& o, const std::vector<PlannedRun>& runs,
                         const std::vector<std::size_t>& pending, RegistryCache& regs, int concurrent, int workers,
                         int hw) {
  std::map<std::string, runtime::EpisodePilot> pilots;
  double episodes = 0, training = 0;
  std::printf(
      "estimate (one core per run; episodes from a pilot of loop 0 and of its offspring and the file's [cost], or "
      "from a resumed run's own loops; training timed by the representation):\n");
  for (std::size_t i : pending) {
    const PlannedRun& r = runs[i];
    Document doc = read_run_document(o, r.file, r.seed, r.overrides);
    const Registry& reg = regs.get(doc.plugin_paths());
    runtime::Experiment ex = runtime::resolve(doc, reg);
    runtime::Components c = runtime::build_components(ex, reg);
    const std::string key = pilot_key(ex.resolved_toml);
    auto it = pilots.find(key);
    runtime::CostEstimate e;
    // A resumed run that has completed a loop past 0 is priced at its own measured rate.
    const MeasuredCost measured = r.first_loop > 1 ? measured_cost(r.dir, ex.settings.iterations) : MeasuredCost{};
    try {
      if (it == pilots.end()) it = pilots.emplace(key, runtime::run_episode_pilot(ex.settings, c)).first;
      e = runtime::estimate_run_cost(ex.settings, c, it->second, r.first_loop,
                                     {measured.core_seconds_per_evaluation, measured.loop});
    } catch (const PluginError& fault) {
      // Plugin code failed while running (the pilot's episodes, the model's timing): as in a run, exit 3.
      throw runtime::WorkerFailure(std::string(fault.what()) + " (in the --dry-run estimate of " + r.label + ")");
    }
    const runtime::EpisodePilot& p = it->second;
    episodes += e.episode_seconds;
    training += e.training_seconds;
    // What priced the episodes: the run's own loops, or the pilot (whose offspring count only for
    // a run that breeds from elites), and the lengthening [cost] adds to a breeding run's.
    char basis[256], growth[96] = "";
    const runtime::CostEstimate::Lengthening& l = e.lengthening;
    if (l.first_loop <= l.last_loop)
      std::snprintf(growth, sizeof growth, "; [cost]: %s x%.2f to x%.2f over loops %d-%d",
                    measured.core_seconds_per_evaluation > 0 ? "that" : "loop 0's", l.from, l.to, l.first_loop,
                    l.last_loop);
    if (measured.core_seconds_per_evaluation > 0)
      std::snprintf(basis, sizeof basis, "measured in its loop %d: %.2f ms/evaluation x %d worker%s%s", measured.loop,
                    1e3 * measured.core_seconds_per_evaluation / measured.workers, measured.workers,
                    measured.workers == 1 ? "" : "s", growth);
    else if (c.mutator->uses_parents())
      std::snprintf(basis, sizeof basis,
                    "loop 0: %.2f ms/episode, %.0f of %d steps, |D| %zu; offspring: %.2f ms/episode, %.0f steps%s",
                    1e3 * p.seconds_per_episode(), p.mean_steps, p.max_steps, p.loop0_archive,
                    1e3 * p.offspring_seconds_per_episode(), p.offspring_mean_steps, growth);
    else
      std::snprintf(basis, sizeof basis, "loop 0: %.2f ms/episode, %.0f of %d steps, |D| %zu",
                    1e3 * p.seconds_per_episode(), p.mean_steps, p.max_steps, p.loop0_archive);
    std::printf("  %-44s %8s core-h: %lld evaluations %s h, training %s h (%s)\n", r.label.c_str(),
                hours(e.total_seconds()).c_str(), e.evaluations, hours(e.episode_seconds).c_str(),
                hours(e.training_seconds).c_str(), basis);
    std::fflush(stdout);
  }
  const int cores = std::max(1, std::min(hw, concurrent * workers));
  std::printf(
      "sweep: estimated %s core-hours (episodes %s, training %s); on this machine, %d at a time on %d core%s: "
      "about %s hours\n",
      hours(episodes + training).c_str(), hours(episodes).c_str(), hours(training).c_str(), concurrent, cores,
      cores == 1 ? "" : "s", hours((episodes + training) / cores).c_str());
}

}  // namespace

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

int run_sweep(const SweepOptions& o,
              const std::function<void(Registry&, const std::vector<std::string>&)>& setup_registry) {
  if (o.experiments.empty()) throw InputError("no experiment file given");
  if (o.jobs < 0 || o.workers < 0) throw InputError("--jobs and --workers must be >= 0");
  if (o.evaluations >= 0)
    for (const auto& s : o.sets)
      if (s.rfind("experiment.loops=", 0) == 0) throw InputError("--evaluations and --set experiment.loops conflict");
  for (const auto& s : o.optional_sets)
    if (s.find('=') == std::string::npos) throw InputError("--set-optional " + s + ": expected KEY=VALUE");

  // Plan and check every run before starting any: bad input anywhere stops the sweep here.
  RegistryCache regs(setup_registry);
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

  const int hw = runtime::hardware_workers();
  std::size_t todo = 0;
  for (const auto& r : runs) todo += r.action != Action::kSkip;
  const int jobs = o.jobs > 0 ? o.jobs : hw;
  const int concurrent =
      static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(jobs), std::max<std::size_t>(todo, 1)));
  // Cores are shared among the runs that run at once; results do not depend on the worker count.
  const int workers = o.workers > 0 ? o.workers : std::max(1, hw / concurrent);
  std::printf("sweep: %zu runs (%zu to do, %zu complete), %d at a time, %d worker%s each\n", runs.size(), todo,
              runs.size() - todo, concurrent, workers, workers == 1 ? "" : "s");
  const std::string exe = fs::read_symlink("/proc/self/exe").string();

  std::size_t skipped = 0, finished = 0;
  std::vector<std::string> failed;
  const std::size_t width = std::to_string(runs.size()).size();
  auto tag = [&](std::size_t i) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "[%*zu/%zu]", static_cast<int>(width), i + 1, runs.size());
    return std::string(buf);
  };
  std::vector<std::size_t> pending;
  for (std::size_t i = 0; i < runs.size(); ++i) {
    if (runs[i].action == Action::kSkip) {
      ++skipped;
      std::printf("%s skip   %s (%s)\n", tag(i).c_str(), runs[i].label.c_str(), runs[i].why.c_str());
    } else {
      pending.push_back(i);
      if (o.dry_run)
        std::printf("%s plan   %s (%s): qdrun", tag(i).c_str(), runs[i].label.c_str(), runs[i].why.c_str());
      if (o.dry_run) {
        for (const auto& a : runs[i].child) std::printf(" %s", a.c_str());
        std::printf("\n");
      }
    }
  }
  std::fflush(stdout);
  if (o.dry_run) {
    print_cost_estimate(o, runs, pending, regs, concurrent, workers, hw);
    return 0;
  }

  // Each run's OpenMP threads (the autoencoder's training) stay within its share of the cores:
  // concurrent runs that each train on every core spin-wait on each other's threads, which made
  // two concurrent Walker fits 3 times slower (docs/performance-history.md). Results do not depend on it.
  if (std::getenv("OMP_THREAD_LIMIT") == nullptr) ::setenv("OMP_THREAD_LIMIT", std::to_string(workers).c_str(), 1);
  std::map<pid_t, std::pair<std::size_t, double>> running;  // pid -> (run, start time)
  const StopForwarding stop_forwarding;
  std::size_t next = 0, stopped = 0;
  while (next < pending.size() || !running.empty()) {
    while (next < pending.size() && static_cast<int>(running.size()) < concurrent && !g_stop_signal) {
      const std::size_t i = pending[next++];
      PlannedRun& r = runs[i];
      // What a run that died before its first checkpoint left (Action::kRestart) is removed by the
      // run itself, under its lock: another qdrun may have taken the directory since it was
      // planned (two sweeps of one output directory), and its files are not the sweep's to delete.
      std::vector<std::string> args = r.child;
      args.insert(args.end(), {"--workers", std::to_string(workers)});  // per-loop lines go to the log
      for (const auto& p : o.plugin_paths) args.insert(args.end(), {"--plugin-path", p});
      pid_t pid = -1;
      try {
        check_unchanged(o, r, regs);
        std::error_code ec;
        fs::create_directories(r.dir, ec);
        if (ec) throw InputError("cannot create the run directory " + r.dir.string() + ": " + ec.message());
        pid = start_child(exe, args, r.dir / "qdrun.log");
      } catch (const Error& e) {
        // This run cannot start (its directory changed since it was planned, no process left):
        // the others go on, and the sweep ends with the runs that failed.
        failed.push_back(r.label);
        std::printf("%s FAILED %s: cannot start it: %s\n", tag(i).c_str(), r.label.c_str(), e.what());
        std::fflush(stdout);
        continue;
      }
      running[pid] = {i, runtime::now_seconds()};
      track_child(pid, true);
      std::printf("%s start  %s (%s)\n", tag(i).c_str(), r.label.c_str(), r.why.c_str());
      std::fflush(stdout);
    }
    if (running.empty()) {
      if (g_stop_signal) break;  // stopped between two runs: none is left to wait for
      continue;                  // every run left failed to start
    }
    int wstatus = 0;
    const pid_t pid = ::waitpid(-1, &wstatus, 0);
    if (pid < 0) {
      if (errno == EINTR) continue;
      throw Error(std::string("waitpid failed: ") + std::strerror(errno));
    }
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    track_child(pid, false);
    const auto [i, t0] = it->second;
    running.erase(it);
    const PlannedRun& r = runs[i];
    const double seconds = runtime::now_seconds() - t0;
    const std::string status = read_text(r.dir / "status");
    if (WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 0 && status.rfind("complete", 0) == 0) {
      ++finished;
      std::printf("%s done   %s in %.1f s\n", tag(i).c_str(), r.label.c_str(), seconds);
    } else if (g_stop_signal && ((WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 128 + g_stop_signal) ||
                                 (WIFSIGNALED(wstatus) && WTERMSIG(wstatus) == g_stop_signal))) {
      ++stopped;
      std::printf("%s stop   %s after %.1f s: %s\n", tag(i).c_str(), r.label.c_str(), seconds,
                  status.substr(0, status.find('\n')).c_str());
    } else {
      failed.push_back(r.label);
      const std::string how = WIFEXITED(wstatus) ? "exit code " + std::to_string(WEXITSTATUS(wstatus))
                                                 : "killed by signal " + std::to_string(WTERMSIG(wstatus));
      std::printf("%s FAILED %s: %s after %.1f s: %s (log %s)\n", tag(i).c_str(), r.label.c_str(), how.c_str(), seconds,
                  last_line(r.dir / "qdrun.log").c_str(), (r.dir / "qdrun.log").c_str());
    }
    std::fflush(stdout);
  }
  if (g_stop_signal) {
    std::printf(
        "sweep: stopped by signal %d (%s): %zu runs finished, %zu stopped, %zu failed, %zu not started; run the same "
        "command again to finish the sweep\n",
        static_cast<int>(g_stop_signal), strsignal(g_stop_signal), finished, stopped, failed.size(),
        pending.size() - next);
    std::fflush(stdout);
    return 128 + g_stop_signal;
  }
  std::printf("sweep: %zu runs: %zu finished, %zu skipped (already complete), %zu failed\n", runs.size(), finished,
              skipped, failed.size());
  if (!failed.empty()) {
    std::printf("sweep: failed runs:");
    for (const auto& f : failed) std::printf(" %s", f.c_str());
    std::printf("\n");
  }
  std::fflush(stdout);
  return failed.empty() ? 0 : 1;
}

}  // namespace qd::app
