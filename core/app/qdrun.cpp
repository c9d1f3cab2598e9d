// qdrun: runs a Quality-Diversity experiment described by a TOML file.
//
// Exit codes (docs/user-guide.md, "Exit codes"): 0 success; 1 internal failure (a bug), or a
// sweep with a failed run; 2 bad input (file, TOML, configuration, options, plugins, run
// directory); 3 a plugin failed during the run (a rollout crashed, exited, hung or threw; plugin
// output broke its contract) or a worker process or MPI rank died or hung; 4 a system or I/O error
// (disk full, a file size limit, no memory, no process or thread, stdout lost); 128 + signal:
// stopped by a stop signal (SIGHUP 129, SIGINT 130, SIGTERM 143, ...), or plugin code crashed in
// qdrun's own process (SIGSEGV 139, SIGABRT 134).
#include "cli.hpp"
#include "describe.hpp"
#include "inspect.hpp"
#include "plugin_hints.hpp"
#include "progress.hpp"
#include "run_guard.hpp"
#include "runtime/components.hpp"
#include "runtime/experiment.hpp"
#include "runtime/registry.hpp"
#include "runtime/replay.hpp"
#include "runtime/run.hpp"
#include "runtime/run_files.hpp"
#include "sweep.hpp"

#include <qd/errors.hpp>
#include <qd/version.hpp>

#include <boost/program_options.hpp>

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <unistd.h>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <map>
#include <new>
#include <system_error>

namespace po = boost::program_options;
namespace fs = std::filesystem;
using namespace qd;
using namespace qd::runtime;
using namespace qd::app;

namespace {

constexpr int kExitOk = 0, kExitFailure = 1, kExitBadInput = 2, kExitWorkerFailure = 3, kExitSystem = 4;

void print_notes(const Cli& cli, const Experiment& ex) {
  if (cli.quiet) return;
  for (const auto& n : ex.notes) std::fprintf(stderr, "qdrun: note: %s\n", n.c_str());
}

int run_one(const Cli& cli, const std::string& command_line) {
  Document doc;
  RunOptions opt;
  if (!cli.resume.empty()) {
    const fs::path cfg = fs::path(cli.resume) / "config.toml";
    if (!fs::exists(cfg)) throw InputError(cli.resume + ": not a run directory (no config.toml)");
    doc = Document::read(cfg);
    for (const auto& s : cli.sets) doc.apply_override(s);  // checked against the checkpoint's config
    if (cli.seed_given || !cli.output.empty()) throw InputError("--seed and --output cannot be combined with --resume");
    if (!cli.backend.empty())
      doc.apply_override("evaluation.backend=" + toml_string(cli.backend), "--backend " + cli.backend);
    opt.directory = cli.resume;
  } else {
    doc = Document::read(cli.experiments.front());
    for (const auto& s : cli.sets) doc.apply_override(s);
    // Through the experiment's schema, as any key: the same ranges, values and messages.
    if (cli.seed_given) doc.apply_override("experiment.seed=" + cli.seed, "--seed " + cli.seed);
    if (!cli.backend.empty())
      doc.apply_override("evaluation.backend=" + toml_string(cli.backend), "--backend " + cli.backend);
    if (!cli.output.empty()) doc.apply_override("output.dir=" + toml_string(cli.output), "--output " + cli.output);
  }
  Registry reg;
  setup_registry(reg, cli, doc.plugin_paths(), doc.recorded_search_path());
  // On --resume a component that cannot be found is reported with the library the run used.
  const fs::path hint_dir = cli.resume.empty() ? fs::path() : fs::path(cli.resume);
  auto build = [&](auto&& f) { return hint_dir.empty() ? f() : with_plugin_hint(hint_dir, reg, f); };
  Experiment ex = build([&] { return resolve(doc, reg); });
  // A sweep's run: the experiment file may have been edited since the sweep planned it.
  if (!cli.planned_config.empty() && app::planned_config_tag(ex.resolved_toml) != cli.planned_config)
    throw InputError(cli.experiments.front() +
                     " (or a file it includes) changed since the sweep planned this run; run the sweep again to "
                     "plan with it");
  print_notes(cli, ex);
  opt.workers = cli.workers;
  opt.stop_after_loop = cli.stop_after_loop;
  opt.command_line = command_line;
  const bool terminal = ::isatty(STDERR_FILENO) != 0;
  app::ProgressPrinter printer(cli.quiet, terminal, ex.settings.name + "/seed-" + std::to_string(ex.settings.seed));
  opt.on_progress = [&](const Progress& p) {
    app::note_position(p.loop, p.iteration);
    printer(p);
  };
  if (mpi_rank() > 0) {
    // An MPI worker rank: same experiment, no files, no output; it serves rank 0 until stopped.
    opt.on_progress = nullptr;
    const auto worker = build([&] { return std::make_unique<Run>(std::move(ex), reg, std::move(opt)); });
    try {
      worker->serve();
    } catch (const PluginError& e) {
      throw WorkerFailure(e.what());  // a plugin fault during the run: exit 3, as on rank 0
    }
    return kExitOk;
  }
  opt.on_start = [] { app::own_run_directory(); };
  const auto owned = build([&] { return std::make_unique<Run>(std::move(ex), reg, std::move(opt)); });
  Run& run = *owned;
  // Guarded before the directory is taken: a stop signal meanwhile ends qdrun with one line, and
  // once the run owns the directory its status says where. Under mpirun, mpirun owns SIGINT and
  // SIGTERM: it ends every rank, and the MPI backend reports it. Fatal signals and exit() in this
  // process are reported in every case.
  app::guard_run(run.directory(), terminal && !cli.quiet, mpi_size() <= 1);
  struct EndOfRun {
    ~EndOfRun() { app::end_of_run(); }
  } end_of_run;
  if (!cli.resume.empty()) {
    check_same_plugins(cli.quiet, run);
    run.open_for_resume();
  } else {
    run.create_directory();
  }
  if (run.restarted() && !cli.quiet)
    std::fprintf(stderr,
                 "qdrun: note: %s held the start of this run, which stopped before its first checkpoint (nothing "
                 "to keep): started again from loop 0\n",
                 run.directory().c_str());
  // One descriptor held back: a run that fails because it ran out of them (ulimit -n, a plugin that
  // leaks them) can still write its status.
  struct Spare {
    int fd = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
    void release() {
      if (fd >= 0) ::close(fd);
      fd = -1;
    }
    ~Spare() { release(); }
  } spare;
  try {
    const bool finished = run.run();
    printer.finish();
    if (!cli.quiet)
      std::fprintf(stderr, "%s: %s (%zu elites, coverage %.4f)\n", finished ? "finished" : "stopped",
                   run.directory().c_str(), run.archive().size(), run.archive().coverage());
  } catch (const std::exception& e) {
    printer.finish();
    // Honest about what is left: a checkpoint to resume from, or nothing worth keeping.
    const std::string dir = run.directory().string();
    const std::string next = CheckpointStore::exists(run.directory())
                                 ? "the last checkpoint is intact: fix the cause and qdrun --resume " + dir
                                 : "no checkpoint was written yet: fix the cause and start again (qdrun --resume " +
                                       dir + " starts it from loop 0)";
    spare.release();
    const std::string what = dynamic_cast<const std::bad_alloc*>(&e) ? "out of memory" : e.what();
    try {
      write_file_atomic(run.directory() / "status", "failed: " + what + " (" + next + ")\n");
    } catch (const std::exception&) {
      // The error itself is what the user must see; the status keeps "running".
    }
    // A plugin fault during the run is exit 3 like a dead worker (setup faults were exit 2).
    if (dynamic_cast<const WorkerFailure*>(&e) || dynamic_cast<const PluginError*>(&e))
      throw WorkerFailure(std::string(e.what()) + "; " + next);
    if (dynamic_cast<const SystemError*>(&e)) throw SystemError(std::string(e.what()) + "; " + next);
    throw;
  }
  return kExitOk;
}

// Values the options' types accept but qdrun cannot use are refused at once, never replaced by a
// default without a word (--seed "", --evaluations -5, --stop-after-loop -1, -o "").
void check_options(const Cli& cli, const po::variables_map& vm) {
  for (const auto& [name, value] : vm) {
    const auto* text = boost::any_cast<std::string>(&value.value());
    if (text && text->empty()) throw InputError("--" + name + " needs a value, and got an empty one");
  }
  if (vm.count("evaluations") && cli.evaluations < 1)
    throw InputError("--evaluations " + std::to_string(cli.evaluations) + ": a budget is at least 1 evaluation");
  if (vm.count("stop-after-loop") && cli.stop_after_loop < 0)
    throw InputError("--stop-after-loop " + std::to_string(cli.stop_after_loop) + ": loops are numbered from 0");
  // As [evaluation] workers: more would only exhaust the process or thread limit.
  if (cli.workers < 0 || cli.workers > 4096)
    throw InputError("--workers " + std::to_string(cli.workers) + " is out of range [0, 4096] (0: all cores)");
  if (cli.jobs < 0 || cli.jobs > 4096)
    throw InputError("--jobs " + std::to_string(cli.jobs) + " is out of range [0, 4096] (0: all cores)");
  for (const auto& p : cli.plugin_paths) {
    if (p.empty()) throw InputError("--plugin-path needs a directory, and got an empty one");
    if (const std::string why = not_a_directory(p); !why.empty())
      throw InputError("--plugin-path " + p + ": " +
                       (why == "does not exist" ? std::string("no such directory") : why));
  }
}

bool sweep_requested(const Cli& cli) {
  return cli.experiments.size() > 1 || !cli.seeds.empty() || cli.jobs > 0 || cli.evaluations >= 0 ||
         !cli.optional_sets.empty() || cli.dry_run;
}

int sweep(const Cli& cli) {
  if (!cli.resume.empty() || cli.seed_given || cli.stop_after_loop >= 0)
    throw InputError("a sweep (several files, --seeds or --jobs) takes no --resume, --seed or --stop-after-loop");
  app::SweepOptions o;
  o.experiments = cli.experiments;
  if (!cli.seeds.empty()) o.seeds = app::parse_seed_list(cli.seeds);
  o.sets = cli.sets;
  o.optional_sets = cli.optional_sets;
  o.plugin_paths = cli.plugin_paths;
  o.output = cli.output;
  o.evaluations = cli.evaluations;
  o.jobs = cli.jobs;
  o.workers = cli.workers;
  o.dry_run = cli.dry_run;
  return app::run_sweep(
      o, [&](Registry& reg, const std::vector<std::string>& from_file) { setup_registry(reg, cli, from_file); });
}

int qdrun_main(int argc, char** argv) {
  // Representations train with OpenMP between evaluation phases; spinning idle OpenMP threads would
  // steal the cores from the evaluation workers. A user's own setting wins.
  ::setenv("OMP_WAIT_POLICY", "passive", 0);
  tune_allocator();
  Cli cli;
  po::options_description visible("qdrun EXPERIMENT.toml [options]\n\nOptions");
  // clang-format off
  visible.add_options()
    ("help,h", po::bool_switch(&cli.help), "show this help")
    ("version", po::bool_switch(&cli.version), "print the version and build fingerprint")
    ("seed", po::value(&cli.seed), "override experiment.seed")
    ("set", po::value(&cli.sets)->composing(), "override a setting: --set mutator.sigma=0.05 (repeatable)")
    ("output,o", po::value(&cli.output), "root output directory (overrides output.dir)")
    ("workers,j", po::value(&cli.workers), "local evaluation workers (default: all cores; results do not depend on it)")
    ("backend", po::value(&cli.backend), "evaluation backend: auto (default: mpi under mpirun, else worker processes that qdrun supervises), processes, threads (inside qdrun, unsupervised) or mpi (overrides [evaluation] backend)")
    ("resume", po::value(&cli.resume), "continue the run in this run directory from its last checkpoint")
    ("quiet,q", po::bool_switch(&cli.quiet), "print nothing but errors")
    ("list", po::bool_switch(&cli.list), "list every available component with its plugin library and version")
    ("describe", po::value(&cli.describe), "print the parameters of a component or of a table (experiment, policy, output, evaluation, plugins, environment, descriptor, representation, mutator, initial)")
    ("plugin-path", po::value(&cli.plugin_paths)->composing(), "extra plugin directory, searched first (repeatable)")
    ("stop-after-loop", po::value(&cli.stop_after_loop), "stop cleanly after this loop's checkpoint (for time-sliced jobs)")
    ("replay", po::value(&cli.replay), "re-run one elite of a finished run and draw it: --replay RUN_DIR --cell N [--svg FILE]")
    ("cell", po::value(&cli.cell), "with --replay: the cell index (column 'index' of archive.csv)")
    ("svg", po::value(&cli.svg), "with --replay: output file (default RUN_DIR/replay-cell-N.svg)")
    ("all", po::bool_switch(&cli.all), "with --replay: re-run every elite and write their trajectories (--traces)")
    ("traces", po::value(&cli.traces), "with --replay --all: output CSV (default RUN_DIR/traces.csv)")
    ("latents", po::value(&cli.latents), "write the latent codes of RUN_DIR's dataset to CSV (-o FILE, default RUN_DIR/latents.csv)");
  po::options_description sweeping("Sweeps: qdrun A.toml B.toml... [--seeds LIST] [options]");
  sweeping.add_options()
    ("seeds", po::value(&cli.seeds), "run every experiment with each seed: 100,200,300 or 1-5")
    ("jobs", po::value(&cli.jobs), "runs at a time (default: all cores; each run gets cores/jobs workers)")
    ("evaluations", po::value(&cli.evaluations), "budget per run: experiment.loops set to reach at least this many evaluations")
    ("set-optional", po::value(&cli.optional_sets)->composing(), "like --set, only for runs whose component has the key (e.g. representation.max_epochs=200)")
    ("dry-run", po::bool_switch(&cli.dry_run), "print what the sweep would do, start nothing");
  visible.add(sweeping);
  // clang-format on
  po::options_description hidden;
  hidden.add_options()("experiment", po::value(&cli.experiments)->composing(), "experiment file")(
      "planned-config", po::value(&cli.planned_config),
      "from a sweep: planned_config_tag of the planned configuration");
  po::options_description all;
  all.add(visible).add(hidden);
  po::positional_options_description pos;
  pos.add("experiment", -1);

  std::string command_line;
  for (int i = 0; i < argc; ++i) command_line += (i ? " " : "") + std::string(argv[i]);

  try {
    po::variables_map vm;
    po::store(po::command_line_parser(argc, argv).options(all).positional(pos).run(), vm);
    po::notify(vm);
    cli.seed_given = vm.count("seed") > 0;
    cli.cell_given = vm.count("cell") > 0;
    check_options(cli, vm);
    // Under mpirun only rank 0 answers questions (help, list, describe, replay); the others wait.
    const bool runs =
        !cli.help && !cli.version && !cli.list && cli.describe.empty() && cli.replay.empty() && cli.latents.empty();
    if (mpi_rank() > 0 && !runs) return kExitOk;
    if (cli.help) {
      std::cout << visible << "\nPlugins are searched in --plugin-path, QD_PLUGIN_PATH, [plugins] path (and, for\n"
                << "a run directory, the directories its config.toml recorded), then <prefix>/lib/qd/plugins.\n"
                << "See docs/user-guide.md.\n";
      return kExitOk;
    }
    if (cli.version) {
      std::printf("qdrun %s (git %s)\nfingerprint %s\ninstruction set %s\n", version_string(), git_revision(),
                  build_fingerprint(), instruction_set());
      return kExitOk;
    }
    if (cli.list || !cli.describe.empty()) {
      Registry reg;
      std::vector<std::string> from_file;
      std::vector<std::string> recorded;
      if (!cli.experiments.empty()) {
        const Document doc = Document::read(cli.experiments.front());
        from_file = doc.plugin_paths();
        recorded = doc.recorded_search_path();
      }
      setup_registry(reg, cli, from_file, recorded);
      if (cli.list)
        list_components(reg);
      else
        describe(reg, cli.describe);
      return kExitOk;
    }
    if (!cli.replay.empty()) return replay(cli);
    if (!cli.latents.empty()) return latents(cli);
    if (sweep_requested(cli)) return sweep(cli);
    if (cli.resume.empty() && cli.experiments.size() != 1)
      throw InputError(cli.experiments.empty() ? "no experiment file given (qdrun EXPERIMENT.toml; see --help)"
                                               : "give one experiment file (or --resume RUN_DIR)");
    if (!cli.resume.empty() && !cli.experiments.empty())
      throw InputError("--resume takes the experiment from the run directory; do not also give an experiment file");
    return run_one(cli, command_line);
  } catch (const po::error& e) {
    std::fprintf(stderr, "qdrun: error: %s (see qdrun --help)\n", e.what());
    return kExitBadInput;
  } catch (const InputError& e) {
    std::fprintf(stderr, "qdrun: error: %s\n", e.what());
    return kExitBadInput;
  } catch (const WorkerFailure& e) {
    std::fprintf(stderr, "qdrun: error: %s\n", e.what());
    std::fflush(stderr);
    // Under MPI a hung or dead rank would never join MPI_Finalize: rank 0 takes the job down,
    // unless the worker ranks were released (a plugin fault the ranks reported). A worker rank
    // returns, so main() prints its captured message before it exits.
    if (mpi_size() > 1 && mpi_rank() == 0 && !mpi_workers_released()) mpi_abort(kExitWorkerFailure);
    return kExitWorkerFailure;
  } catch (const SystemError& e) {
    std::fprintf(stderr, "qdrun: system error: %s\n", e.what());
    return kExitSystem;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "qdrun: system error: out of memory\n");
    return kExitSystem;
  } catch (const std::system_error& e) {
    // The system refused a thread, a lock or a file operation (std::thread, std::filesystem).
    std::fprintf(stderr, "qdrun: system error: %s\n", e.what());
    return kExitSystem;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "qdrun: internal failure: %s\n", e.what());
    return kExitFailure;
  }
}

// Standard descriptors that a launcher closed (qdrun FILE 2>&-) would be taken by the next file or
// socket qdrun opens, and progress text would land in it (the lock file, metrics.csv, a worker's
// socket). /dev/null takes their place before anything else is opened.
bool make_standard_descriptors_safe() {
  for (int fd = STDIN_FILENO; fd <= STDERR_FILENO; ++fd) {
    if (::fcntl(fd, F_GETFD) != -1 || errno != EBADF) continue;
    const int null = ::open("/dev/null", fd == STDIN_FILENO ? O_RDONLY : O_WRONLY);
    if (null < 0) return false;
    if (null != fd) {  // cannot happen (the lowest free descriptor is fd), but never leave it open
      ::dup2(null, fd);
      ::close(null);
    }
  }
  return true;
}

// What qdrun printed on stdout (a listing, a description, a sweep's plan) must have arrived: a
// full disk or a closed pipe there is a failure, not success.
int check_standard_output(int code) {
  errno = 0;
  const bool flushed = std::fflush(stdout) == 0;
  int e = errno;
  if (flushed && !std::ferror(stdout)) return code;
  // An earlier write failed; a pipe whose reader went away still says so.
  if (pollfd p{STDOUT_FILENO, POLLOUT, 0}; e == 0 && ::poll(&p, 1, 0) == 1 && (p.revents & POLLERR)) e = EPIPE;
  std::fprintf(stderr, "qdrun: system error: cannot write to standard output%s%s: what qdrun printed there is lost\n",
               e ? ": " : "", e ? std::strerror(e) : "");
  return code == kExitOk ? kExitSystem : code;
}

}  // namespace

int main(int argc, char** argv) {
  if (!make_standard_descriptors_safe()) return kExitSystem;  // cannot even open /dev/null: nothing is safe
  // A file size limit (ulimit -f) is a write error like a full disk (exit 4 naming the file), not
  // a silent kill by SIGXFSZ.
  ::signal(SIGXFSZ, SIG_IGN);
  // What a launcher may leave behind that qdrun cannot work with: SIGCHLD ignored (children would
  // be reaped by the kernel, and qdrun could not tell how its worker processes, plugin probes and
  // sweep runs ended), or a crash signal blocked (a fault would end qdrun without its report).
  ::signal(SIGCHLD, SIG_DFL);
  sigset_t crashes;
  sigemptyset(&crashes);
  for (const int sig : {SIGCHLD, SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT, SIGSYS, SIGTRAP}) sigaddset(&crashes, sig);
  ::sigprocmask(SIG_UNBLOCK, &crashes, nullptr);
  try {
    mpi_start(&argc, &argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "qdrun: internal failure: %s\n", e.what());
    return kExitFailure;
  }
  if (mpi_rank() > 0) {
    // Worker ranks stay quiet: rank 0 reports. An error only a worker has (a plugin missing on its
    // node) is printed after a grace period in which a shared error ends the job from rank 0.
    std::string err;
    int code = kExitOk;
    {
      std::fflush(stdout);
      const int saved = ::dup(STDERR_FILENO);
      std::FILE* capture = std::tmpfile();
      if (capture) ::dup2(::fileno(capture), STDERR_FILENO);
      code = qdrun_main(argc, argv);
      std::fflush(stderr);
      if (capture) {
        ::dup2(saved, STDERR_FILENO);
        std::rewind(capture);
        char buf[4096];
        std::size_t got = 0;
        while ((got = std::fread(buf, 1, sizeof(buf), capture)) > 0) err.append(buf, got);
        std::fclose(capture);
      }
      ::close(saved);
    }
    if (code != kExitOk) {
      ::sleep(2);
      std::fprintf(stderr, "qdrun (MPI rank %d): %s", mpi_rank(), err.c_str());
      std::fflush(stderr);
      // Not MPI_Finalize: it would wait for ranks that fail the same way; an exit without it makes
      // mpirun end the job.
      std::_Exit(code);
    }
    mpi_stop();
    return code;
  }
  const int code = check_standard_output(qdrun_main(argc, argv));
  if (code != kExitOk && mpi_size() > 1 && !mpi_workers_released()) {
    std::fflush(nullptr);
    std::_Exit(code);  // see above: mpirun ends the job, the worker ranks included
  }
  mpi_stop();
  return code;
}
