#include "runtime/run.hpp"

#include "runtime/archive_csv.hpp"
#include "runtime/clock.hpp"
#include "runtime/number_text.hpp"
#include "runtime/run_files.hpp"

#include <qd/errors.hpp>
#include <qd/version.hpp>

#include <malloc.h>
#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <sstream>

namespace qd::runtime {
namespace fs = std::filesystem;

namespace {

std::string utc_now() {
  const std::time_t t = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  return "unknown";
}

fs::path run_directory_of(const ExperimentSettings& s, const RunOptions& opt) {
  return opt.directory.empty() ? fs::path(s.output_dir) / s.name / ("seed-" + std::to_string(s.seed))
                               : fs::path(opt.directory);
}

// Bytes the system can still give this process (MemAvailable), 0 when unknown.
std::uint64_t available_memory() {
  std::ifstream in("/proc/meminfo");
  std::string key, unit;
  std::uint64_t kb = 0;
  while (in >> key >> kb >> unit)
    if (key == "MemAvailable:") return kb * 1024;
  return 0;
}

std::string gigabytes(double bytes) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.1f GB", bytes / 1e9);
  return buf;
}

// Refuses a run that cannot fit in memory before anything is allocated, instead of being killed
// by the kernel later: the batch buffers (offspring, parents, the process backend's shared copy)
// and, at worst, an archive, a dataset and a checkpoint buffer with one policy in every cell the
// budget can reach.
void check_memory(const ExperimentSettings& s, const Components& c) {
  const double P = static_cast<double>(c.shape.param_count());
  const double batch = std::max(s.batch, s.initial_samples);
  const double batches = 4.0 * batch * P * 8.0;
  const double budget = s.initial_samples + static_cast<double>(s.loops - 1) * s.iterations * s.batch;
  const double stores = 3.0 * std::min(static_cast<double>(c.grid.cells), budget) * P * 8.0;
  const std::uint64_t available = available_memory();
  if (available > 0 && batches + stores > static_cast<double>(available))
    throw InputError("the run needs about " + gigabytes(batches + stores) + " of memory (batches of " +
                     std::to_string(static_cast<long long>(batch)) + " policies of " +
                     std::to_string(c.shape.param_count()) + " parameters: " + gigabytes(batches) +
                     "; archive and dataset: up to " + gigabytes(stores) + "), but " +
                     gigabytes(static_cast<double>(available)) +
                     " are available; lower experiment.batch or experiment.initial_samples");
}

// The components of the run in `dir`; a run that already has a checkpoint there is being opened
// (resumed, replayed, inspected), and descriptors that compute their grid reuse the stored one.
Components build_run_components(Experiment& ex, const Registry& registry, const fs::path& dir) {
  GridSpec stored;
  bool have = false;
  if (CheckpointStore::exists(dir)) {
    try {
      have = read_stored_grid(dir, stored);
    } catch (const StateError& e) {
      throw InputError(dir.string() + ": cannot open the run: " + e.what() +
                       "; restore the file, or delete the run directory and start again");
    }
  }
  return build_components(ex, registry, have ? &stored : nullptr);
}

std::unique_ptr<Evaluator> make_run_evaluator(const Experiment& ex, const Components& c, const RunOptions& opt,
                                              const fs::path& dir) {
  const ExperimentSettings& s = ex.settings;
  check_memory(s, c);
  EvaluatorSpec spec;
  spec.workers = opt.workers > 0 ? opt.workers : (s.workers > 0 ? s.workers : hardware_workers());
  spec.backend = s.backend;
  spec.capacity = static_cast<std::size_t>(std::max(s.batch, s.initial_samples));
  spec.timeout_seconds = s.timeout_seconds;
  spec.status_file = (dir / "status").string();
  spec.labels = {c.environment_label, c.descriptor_label};
  return make_evaluator(spec, *c.environment, *c.descriptor, c.shape);
}

}  // namespace

void tune_allocator() {
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 1024 << 20);
}

Run::Run(Experiment experiment, const Registry& registry, RunOptions options)
    : ex_(std::move(experiment)),
      opt_(std::move(options)),
      c_(build_run_components(ex_, registry, run_directory_of(ex_.settings, opt_))),
      evaluator_(make_run_evaluator(ex_, c_, opt_, run_directory_of(ex_.settings, opt_))),
      archive_(c_.grid.cells, c_.shape.param_count(), c_.grid.dims()),
      dataset_(c_.shape.param_count()),
      dir_(run_directory_of(ex_.settings, opt_)),
      checkpoints_(dir_.path(), c_.shape.param_count(), c_.grid.dims()),
      loop_(ex_.settings, c_, *evaluator_, archive_, dataset_, *this) {
  const auto& names = c_.metric_names;
  const auto mixing = std::find(names.begin(), names.end(), kMixingRatio);
  if (mixing != names.end()) mixing_metric_ = static_cast<std::size_t>(mixing - names.begin());
}

Run::~Run() = default;

void Run::create_directory() {
  std::string header =
      "loop,iteration,evaluations,elites,coverage,qd_score,max_fitness,mean_fitness,mixing_ratio,added,replaced,"
      "invalid,wall_seconds,train_seconds";
  for (std::size_t k = 0; k < c_.metric_names.size(); ++k)
    if (k != mixing_metric_) header += "," + c_.metric_names[k];
  restarted_ = dir_.create(ex_.resolved_toml, header);
  if (opt_.on_start) opt_.on_start();
  dir_.set_status("running");
  write_grid();
  write_provenance();
  next_loop_ = 0;
}

void Run::write_grid() const {
  if (c_.grid.is_cvt()) dir_.write("centroids.csv", centroids_csv(c_.grid));  // grid.toml records its CRC
  dir_.write("grid.toml", grid_toml(c_.grid));
}

void Run::open_for_resume() {
  if (!CheckpointStore::exists(dir_.path())) {
    std::string found;
    if (RunDirectory::leftover(dir_.path(), &found) == Leftover::kResults)
      throw InputError(dir_.path().string() + ": cannot resume: " + (dir_.path() / "checkpoint.bin").string() +
                       " is missing, but the run has results (" + found +
                       "); restore checkpoint.bin, or move the directory away and start the run again");
    // It stopped before its first checkpoint: nothing to keep, so resuming is starting again.
    create_directory();
    return;
  }
  dir_.open();
  load_checkpoint(true);
  if (opt_.on_start) opt_.on_start();
  dir_.write_config(ex_.resolved_toml);
  write_grid();
  dir_.set_status("running");
  write_provenance();
}

void Run::open_for_inspection() {
  if (!CheckpointStore::exists(dir_.path()))
    throw InputError(dir_.path().string() + " has no checkpoint (the run stopped before the end of loop 0)");
  load_checkpoint(false);
}

std::vector<std::string> Run::log_names() const {
  std::vector<std::string> names = {"metrics.csv", "training.csv"};
  names.insert(names.end(), training_logs_.begin(), training_logs_.end());
  return names;
}

void Run::append(const std::string& name, const std::string& header, const std::string& rows) {
  bool restart = false;
  if (std::find(training_logs_.begin(), training_logs_.end(), name) == training_logs_.end()) {
    if (!is_training_log_name(name))
      throw PluginError(c_.representation_label + " asked to log to '" + name +
                        "': a training log is a plain file name ending in .csv that is not one of the run's own "
                        "files");
    training_logs_.push_back(name);
    // In a resumed run no checkpoint vouches for a file of this name already there (a session
    // that stopped before its next checkpoint wrote it): the log starts again.
    restart = resumed_;
  }
  try {
    dir_.append_log(name, header, rows, restart);
  } catch (...) {
    log_failure_ = std::current_exception();  // fails the run even if fit() swallows it
    throw;
  }
}

void Run::load_checkpoint(bool resuming) {
  const ExperimentSettings& s = ex_.settings;
  try {
    const CheckpointStore::Loaded loaded = checkpoints_.load(archive_, dataset_, checkpointed_components(), resuming);
    const CheckpointCounters& n = loaded.counters;
    if (resuming) {
      // The configuration stored in the checkpoint is the truth; config.toml is a readable copy.
      for (const ConfigDifference& d : config_differences(loaded.config, ex_.resolved_toml)) {
        if (!may_change_on_resume(d.key) && d.before == "(absent)")
          throw InputError(dir_.path().string() +
                           ": cannot resume: the run was made by an older qdrun or plugin, which had no " + d.key +
                           " (and wrote other files); finish it with the build that made it (provenance.toml "
                           "names its git revision and plugins)");
        if (!may_change_on_resume(d.key))
          throw InputError(dir_.path().string() + ": cannot resume: " + d.key + " is " + d.after +
                           " in config.toml (or --set) but the run was made with " + d.before +
                           "; only experiment.loops and the [evaluation], [output] and [plugins] keys may change" +
                           (d.key == "experiment.name" ? " (the run directory is named after experiment.name)" : ""));
      }
      if (n.loop + 1 > s.loops)
        throw InputError(dir_.path().string() + ": cannot resume: experiment.loops = " + std::to_string(s.loops) +
                         " is below the " + std::to_string(n.loop + 1) + " loops that have run");
    }
    // The counters against each other and, when resuming, against the logs.
    const std::uint64_t expected = static_cast<std::uint64_t>(s.initial_samples) +
                                   static_cast<std::uint64_t>(n.loop) * static_cast<std::uint64_t>(s.iterations) *
                                       static_cast<std::uint64_t>(s.batch);
    if (n.loop < 0 || n.evaluations != expected || archive_.size() > dataset_.size())
      throw StateError("checkpoint.bin: its counters disagree (loop " + std::to_string(n.loop) + ", " +
                       std::to_string(n.evaluations) + " evaluations, " + std::to_string(archive_.size()) +
                       " elites, " + std::to_string(dataset_.size()) + " dataset rows)");
    if (resuming) {
      resumed_ = true;
      for (const LogSize& log : loaded.logs)  // the representation's logs the checkpoint vouches for
        if (log.name != "metrics.csv" && log.name != "training.csv") training_logs_.push_back(log.name);
      dir_.cut_logs(loaded.logs, log_names());
      const std::size_t rows = dir_.count_lines("metrics.csv"),
                        want = 2 + static_cast<std::size_t>(n.loop) * s.iterations;
      if (rows != want)
        throw StateError("metrics.csv has " + std::to_string(rows) + " lines where the checkpoint of loop " +
                         std::to_string(n.loop) + " expects " + std::to_string(want) + ": it was edited");
    }
    loop_.set_evaluations(n.evaluations);
    wall_before_ = n.wall_seconds;
    train_seconds_ = n.train_seconds;
    next_loop_ = n.loop + 1;
  } catch (const StateError& e) {
    throw InputError(dir_.path().string() + ": cannot resume: " + e.what() +
                     "; restore the file, or delete the run directory and start again");
  }
}

bool Run::run() {
  session_start_ = now_seconds();
  session_first_evaluation_ = loop_.evaluations();
  const ExperimentSettings& s = ex_.settings;
  while (next_loop_ < s.loops) {
    const int loop = next_loop_++;
    try {
      loop_.run_loop(loop);
    } catch (const PluginError&) {
      // A representation that let the training log's own error through is not at fault: the
      // log's error (a full disk, a symlink in the log's place) is what the user must see.
      if (log_failure_) std::rethrow_exception(log_failure_);
      throw;
    }
    if (s.snapshot_every > 0 && loop % s.snapshot_every == 0) {
      // The snapshots' directory is the run's own, never a symlink out of it.
      const fs::path snapshots = dir_.path() / "archive";
      std::error_code ec;
      const fs::file_status st = fs::symlink_status(snapshots, ec);
      if (fs::exists(st) && !fs::is_directory(st))
        throw InputError(snapshots.string() + " is not a directory of the run (a symlink or a file); move it away");
      fs::create_directories(snapshots);
      char name[32];
      std::snprintf(name, sizeof(name), "loop-%05d.csv", loop);
      write_archive_csv(dir_.path() / "archive" / name, archive_, s.snapshot_parameters);
    }
    save_checkpoint(loop);
    report(loop, s.iterations - 1, true);
    if (opt_.stop_after_loop >= 0 && loop >= opt_.stop_after_loop && next_loop_ < s.loops) {
      checkpoints_.wait();
      dir_.set_status("stopped after loop " + std::to_string(loop) + " (resume with --resume)");
      return false;
    }
  }
  write_archive_csv(dir_.path() / "archive.csv", archive_, s.snapshot_parameters);
  checkpoints_.wait();
  dir_.set_status("complete");
  return true;
}

void Run::save_checkpoint(int loop) {
  const CheckpointCounters counters{loop, loop_.evaluations(), wall_seconds(), train_seconds_};
  checkpoints_.save(counters, ex_.resolved_toml, dir_.log_sizes(log_names()), archive_, dataset_,
                    checkpointed_components());
}

CheckpointStore::Components Run::checkpointed_components() const {
  Environment* worlds = c_.environment->info().persistent_worlds > 0 ? c_.environment.get() : nullptr;
  return {c_.representation.get(), c_.mutator.get(), c_.initial.get(), worlds};
}

double Run::wall_seconds() const {
  return wall_before_ + (now_seconds() - session_start_);
}

void Run::iteration_done(const IterationOutcome& o) {
  std::string& row = metrics_row_;
  row.clear();
  for (const std::int64_t v :
       {std::int64_t{o.loop}, std::int64_t{o.iteration}, static_cast<std::int64_t>(loop_.evaluations()),
        static_cast<std::int64_t>(archive_.size())}) {
    append_int(row, v);
    row += ',';
  }
  append_number(row, archive_.coverage());
  // QD metrics; empty where they do not apply (a task without fitness, no declared lower bound).
  const QdMetrics q = qd_metrics(archive_, c_.has_fitness, c_.fitness_lower_bound);
  for (const double v : {q.qd_score, q.max_fitness, q.mean_fitness}) {
    row += ',';
    if (!std::isnan(v)) append_number(row, v);
  }
  row += ',';
  const std::vector<double>& metrics = o.offspring->metrics;
  if (mixing_metric_ < metrics.size() && !std::isnan(metrics[mixing_metric_]))
    append_number(row, metrics[mixing_metric_]);
  for (const std::size_t v : {o.added, o.replaced, o.invalid}) {
    row += ',';
    append_int(row, static_cast<std::int64_t>(v));
  }
  row += ',';
  append_number(row, wall_seconds());
  row += ',';
  append_number(row, train_seconds_);
  for (std::size_t k = 0; k < c_.metric_names.size(); ++k) {
    if (k == mixing_metric_) continue;
    row += ',';
    if (k < metrics.size()) append_number(row, metrics[k]);
  }
  row += '\n';
  dir_.append_metrics(row);
  report(o.loop, o.iteration, false);
}

void Run::training_started(int loop) {
  report(loop, ex_.settings.iterations - 1, false, "training " + c_.representation_type);
}

void Run::training_done(int loop, const FitReport& r, double seconds) {
  if (log_failure_) std::rethrow_exception(log_failure_);
  train_seconds_ += seconds;
  std::string row;
  append_int(row, loop);
  row += ',';
  append_int(row, r.epochs);
  row += ',';
  append_number(row, r.train_loss);
  row += ',';
  if (!std::isnan(r.test_loss)) append_number(row, r.test_loss);
  row += r.stopped_early ? ",1," : ",0,";
  append_number(row, seconds);
  dir_.append_training(row + "\n");
}

std::string Run::fault_offspring(int loop, int it, std::size_t first, std::size_t last, const Matrix& theta,
                                 const std::vector<std::uint64_t>& seeds) {
  const std::string path = dir_.path().string() + "/fault-offspring.csv";
  std::string text = "loop,iteration,offspring,episode_seed";
  for (Eigen::Index p = 0; p < theta.cols(); ++p) text += ",solution_" + std::to_string(p);
  text += '\n';
  for (std::size_t k = first; k <= last; ++k) {
    for (const std::int64_t v : {std::int64_t{loop}, std::int64_t{it}, static_cast<std::int64_t>(k)}) {
      append_int(text, v);
      text += ',';
    }
    text += std::to_string(seeds[k]);
    for (Eigen::Index p = 0; p < theta.cols(); ++p) {
      text += ',';
      append_number(text, theta(static_cast<Eigen::Index>(k), p));
    }
    text += '\n';
  }
  try {
    write_file_atomic(path, text);
  } catch (const std::exception&) {
    return "";  // the fault itself is what the user must see
  }
  return path;
}

void Run::write_provenance() const {
  std::ostringstream o;
  char host[256] = {0};
  ::gethostname(host, sizeof(host) - 1);
  o << "qd_version = " << toml_string(version_string()) << "\n"
    << "git_revision = " << toml_string(git_revision()) << "\n"
    << "build_fingerprint = " << toml_string(build_fingerprint()) << "\n"
    << "instruction_set = " << toml_string(instruction_set()) << "\n"
    << "host = " << toml_string(host) << "\n"
    << "cpu = " << toml_string(cpu_model()) << "\n"
    << "hardware_threads = " << hardware_workers() << "\n"
    << "workers = " << evaluator_->workers() << "\n"
    << "backend = " << toml_string(evaluator_->backend()) << "\n"
    << "seed = " << ex_.settings.seed << "\n"
    << "started = " << toml_string(utc_now()) << "\n"
    << "resumed_at_loop = " << next_loop_ << "\n"
    << "command = " << toml_string(opt_.command_line) << "\n"
    << "experiment_file = " << toml_string(ex_.file.string()) << "\n"
    << "policy_parameters = " << c_.shape.param_count() << "\n"
    << "cells = " << archive_.cells() << "\n"
    << "plugins = [\n";
  for (const auto& line : c_.provenance) o << "  " << line << ",\n";
  o << "]\n";
  dir_.write_provenance(next_loop_, o.str());
}

void Run::report(int loop, int iteration, bool loop_finished, const std::string& note) {
  if (!opt_.on_progress) return;
  const ExperimentSettings& s = ex_.settings;
  Progress p;
  p.loop = loop;
  p.loops = s.loops;
  p.iteration = iteration;
  p.evaluations = loop_.evaluations();
  p.total_evaluations = static_cast<std::uint64_t>(s.initial_samples) + static_cast<std::uint64_t>(s.loops - 1) *
                                                                            static_cast<std::uint64_t>(s.iterations) *
                                                                            static_cast<std::uint64_t>(s.batch);
  p.elites = archive_.size();
  p.coverage = archive_.coverage();
  p.wall_seconds = now_seconds() - session_start_;
  p.session_evaluations = loop_.evaluations() - session_first_evaluation_;
  p.loop_finished = loop_finished;
  p.note = note;
  opt_.on_progress(p);
}

}  // namespace qd::runtime
