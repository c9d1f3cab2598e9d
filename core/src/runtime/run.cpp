#include "runtime/run.hpp"

#include "runtime/csv.hpp"
#include "runtime/number_format.hpp"

#include <qd/errors.hpp>
#include <qd/state_io.hpp>
#include <qd/version.hpp>

#include <malloc.h>
#include <unistd.h>
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <numeric>
#include <sstream>

namespace qd::runtime {
namespace fs = std::filesystem;

namespace {
constexpr char kCheckpointMagic[8] = {'Q', 'D', 'C', 'K', 'P', 'T', '0', '2'};
constexpr const char* kCheckpointFile = "checkpoint.bin";
// Checkpoint format 02: the archive and the dataset live in append-only files beside the checkpoint.
constexpr char kDatasetMagic[8] = {'Q', 'D', 'D', 'S', 'E', 'T', '0', '1'};
constexpr const char* kDatasetFile = "dataset.bin";
constexpr char kArchiveLogMagic[8] = {'Q', 'D', 'A', 'R', 'L', 'G', '0', '1'};

// One dataset row in dataset.bin: cell (int64), loop (int64), then P doubles.
std::size_t dataset_row_bytes(std::size_t P) {
  return 2 * sizeof(std::int64_t) + P * sizeof(double);
}

double now_seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

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

std::string toml_string(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    out += c;
  }
  return out + "\"";
}

// Files the loop appends to; a checkpoint records their sizes and resume truncates them back.
bool is_appended_log(const fs::path& p) {
  return p.extension() == ".csv" && p.filename() != "archive.csv";
}

}  // namespace

void tune_allocator() {
  mallopt(M_MMAP_THRESHOLD, 256 << 20);
  mallopt(M_TRIM_THRESHOLD, 1024 << 20);
}

Run::Run(Experiment experiment, const Registry& registry, RunOptions options)
    : ex_(std::move(experiment)), opt_(std::move(options)) {
  const auto& s = ex_.settings;
  dir_ = opt_.directory.empty() ? fs::path(s.output_dir) / s.name / ("seed-" + std::to_string(s.seed))
                                : fs::path(opt_.directory);

  auto located = [](const ComponentConfig& cc, auto&& build) {
    try {
      return build();
    } catch (const ConfigError& e) {
      throw ConfigError(e.key(), cc.config.where(e.key()) + ": [" + cc.table + "]." + e.key() + ": " + e.what());
    }
  };

  BuildContext ctx;
  ctx.seed = s.seed;
  env_ = located(ex_.environment,
                 [&] { return registry.create<Environment>(*ex_.environment.entry, ex_.environment.config, ctx); });
  const EnvironmentInfo info = env_->info();
  if (info.observation_size <= 0 || info.action_size <= 0)
    throw PluginError("environment '" + ex_.environment.type + "' reports no observation or action size");
  shape_ = PolicyShape(info.observation_size, s.hidden, info.action_size);
  ctx.policy = &shape_;

  if (!ex_.descriptor.entry) {
    if (info.default_descriptor.empty())
      throw InputError("environment '" + ex_.environment.type +
                       "' has no default descriptor; add [descriptor] type = ...");
    resolve_default_component(ex_, ex_.descriptor, registry.require(info.default_descriptor, Kind::kDescriptor));
  }
  desc_ = located(ex_.descriptor,
                  [&] { return registry.create<Descriptor>(*ex_.descriptor.entry, ex_.descriptor.config, ctx); });
  const GridSpec grid = desc_->grid();
  if (grid.cells <= 0 || grid.shape.empty())
    throw PluginError("descriptor '" + ex_.descriptor.type + "' declares an empty grid");

  repr_ = located(ex_.representation, [&] {
    return registry.create<Representation>(*ex_.representation.entry, ex_.representation.config, ctx);
  });
  const int latent = repr_->latent_size();
  if (latent < 0 || static_cast<std::size_t>(latent) > shape_.param_count())
    throw ConfigError("latent", ex_.representation.config.where("latent") + ": [representation] latent size " +
                                    std::to_string(latent) + " is larger than the policy's parameter count " +
                                    std::to_string(shape_.param_count()));
  ctx.latent_size = latent;
  mutator_ =
      located(ex_.mutator, [&] { return registry.create<Mutator>(*ex_.mutator.entry, ex_.mutator.config, ctx); });
  initial_ =
      located(ex_.initial, [&] { return registry.create<Mutator>(*ex_.initial.entry, ex_.initial.config, ctx); });
  if (initial_->uses_parents())
    throw InputError("[initial] type = \"" + ex_.initial.type +
                     "\" needs parents, but loop 0 has none; use a sampler such as \"uniform\" or \"glorot\"");
  for (const auto* m : {&ex_.mutator, &ex_.initial}) {
    const Mutator& obj = m == &ex_.mutator ? *mutator_ : *initial_;
    if (obj.needs_latent() && latent == 0)
      throw InputError("[" + m->table + "] type = \"" + m->type +
                       "\" needs a representation with a latent space, but [representation] type = \"" +
                       ex_.representation.type + "\" has none (use \"autoencoder\" or \"pca\")");
  }
  mutator_metric_names_ = mutator_->metric_names();

  for (const ComponentConfig* cc :
       {&ex_.environment, &ex_.descriptor, &ex_.representation, &ex_.mutator, &ex_.initial}) {
    const PluginInfo& pi = *cc->entry->plugin->info;
    plugin_lines_.push_back("{ table = " + toml_string(cc->table) + ", component = " + toml_string(cc->type) +
                            ", plugin = " + toml_string(pi.plugin_name) + ", version = " +
                            toml_string(pi.plugin_version) + ", path = " + toml_string(cc->entry->plugin->path) + " }");
  }

  EvaluatorSpec spec;
  spec.workers = opt_.workers > 0 ? opt_.workers : (s.workers > 0 ? s.workers : hardware_workers());
  spec.backend = opt_.backend.empty() ? s.backend : opt_.backend;
  spec.capacity = static_cast<std::size_t>(std::max(s.batch, s.initial_samples));
  spec.timeout_seconds = s.timeout_seconds;
  spec.status_file = (dir_ / "status").string();
  evaluator_ = make_evaluator(spec, *env_, *desc_, shape_);
  archive_ = std::make_unique<Archive>(grid.cells, shape_.param_count(), grid.shape.size());
  dataset_ = std::make_unique<Dataset>(shape_.param_count());
  one_buffer_ = choose_one_offspring_buffer();
  metrics_path_ = dir_ / "metrics.csv";
}

Run::~Run() = default;

void Run::create_directory() {
  std::error_code ec;
  if (fs::exists(dir_ / "config.toml", ec) || fs::exists(dir_ / kCheckpointFile, ec))
    throw InputError(dir_.string() + " already holds a run; continue it with --resume " + dir_.string() +
                     ", or choose another --output, --seed or experiment.name");
  fs::create_directories(dir_, ec);
  if (ec) throw InputError("cannot create the run directory " + dir_.string() + ": " + ec.message());
  if (::access(dir_.c_str(), W_OK) != 0) throw InputError("the run directory " + dir_.string() + " is not writable");
  set_status("running");
  write_file_atomic(dir_ / "config.toml", ex_.resolved_toml);
  write_provenance();
  std::string header =
      "loop,iteration,evaluations,elites,coverage,mixing_ratio,added,replaced,invalid,wall_seconds,train_seconds";
  for (const auto& n : mutator_metric_names_) header += "," + n;
  write_file_atomic(metrics_path_, header + "\n");
  write_file_atomic(dir_ / "training.csv", "loop,epochs,train_loss,test_loss,stopped_early,seconds\n");
  next_loop_ = 0;
}

void Run::open_for_resume() {
  std::error_code ec;
  if (!fs::exists(dir_ / kCheckpointFile, ec))
    throw InputError(dir_.string() + " has no checkpoint to resume from (the run stopped before the end of loop 0)");
  if (::access(dir_.c_str(), W_OK) != 0) throw InputError("the run directory " + dir_.string() + " is not writable");
  load_checkpoint(true);
  write_file_atomic(dir_ / "config.toml", ex_.resolved_toml);
  set_status("running");
  write_provenance();
}

void Run::open_for_inspection() {
  std::error_code ec;
  if (!fs::exists(dir_ / kCheckpointFile, ec))
    throw InputError(dir_.string() + " has no checkpoint (the run stopped before the end of loop 0)");
  load_checkpoint(false);
}

double Run::wall_seconds() const {
  return wall_before_ + (now_seconds() - session_start_);
}

void Run::set_status(const std::string& status) const {
  write_file_atomic(dir_ / "status", status + "\n");
}

void Run::write_provenance() const {
  std::ostringstream o;
  char host[256] = {0};
  ::gethostname(host, sizeof(host) - 1);
  o << "qd_version = " << toml_string(version_string()) << "\n"
    << "git_revision = " << toml_string(git_revision()) << "\n"
    << "build_fingerprint = " << toml_string(build_fingerprint()) << "\n"
    << "host = " << toml_string(host) << "\n"
    << "cpu = " << toml_string(cpu_model()) << "\n"
    << "hardware_threads = " << hardware_workers() << "\n"
    << "workers = " << evaluator_->workers() << "\n"
    << "backend = " << toml_string(evaluator_->backend()) << "\n"
    << "offspring_buffers = " << toml_string(one_buffer_ ? "one" : "two") << "\n"
    << "l2_cache_bytes = " << core_l2_cache_bytes() << "\n"
    << "seed = " << ex_.settings.seed << "\n"
    << "started = " << toml_string(utc_now()) << "\n"
    << "resumed_at_loop = " << next_loop_ << "\n"
    << "command = " << toml_string(opt_.command_line) << "\n"
    << "experiment_file = " << toml_string(ex_.file.string()) << "\n"
    << "policy_parameters = " << shape_.param_count() << "\n"
    << "cells = " << archive_->cells() << "\n"
    << "plugins = [\n";
  for (const auto& line : plugin_lines_) o << "  " << line << ",\n";
  o << "]\n";
  // One file per session, so the provenance of each part of a resumed run is kept.
  const std::string name =
      next_loop_ == 0 ? "provenance.toml" : "provenance-resume-loop-" + std::to_string(next_loop_) + ".toml";
  write_file_atomic(dir_ / name, o.str());
}

void Run::report(int loop, int iteration, bool loop_finished, const std::string& note) {
  if (!opt_.on_progress) return;
  Progress p;
  const auto& s = ex_.settings;
  p.loop = loop;
  p.loops = s.loops;
  p.iteration = iteration;
  p.evaluations = evaluations_;
  p.total_evaluations = static_cast<std::uint64_t>(s.initial_samples) + static_cast<std::uint64_t>(s.loops - 1) *
                                                                            static_cast<std::uint64_t>(s.iterations) *
                                                                            static_cast<std::uint64_t>(s.batch);
  p.elites = archive_->size();
  p.coverage = archive_->coverage();
  p.wall_seconds = now_seconds() - session_start_;
  p.session_evaluations = session_evaluations_;
  p.loop_finished = loop_finished;
  p.note = note;
  opt_.on_progress(p);
}

void Run::serve() {
  evaluator_->serve();
}

bool Run::run() {
  session_start_ = now_seconds();
  const int loops = ex_.settings.loops;
  while (next_loop_ < loops) {
    const int loop = next_loop_;
    if (loop == 0)
      loop_zero();
    else
      map_elites_loop(loop);
    fit_representation(loop);
    next_loop_ = loop + 1;
    const int every = ex_.settings.snapshot_every;
    if (every > 0 && loop % every == 0) {
      fs::create_directories(dir_ / "archive");
      char name[32];
      std::snprintf(name, sizeof(name), "loop-%05d.csv", loop);
      write_snapshot(dir_ / "archive" / name);
    }
    write_checkpoint(loop);
    report(loop, ex_.settings.iterations - 1, true);
    if (opt_.stop_after_loop >= 0 && loop >= opt_.stop_after_loop && next_loop_ < loops) {
      finish_checkpoints();
      set_status("stopped after loop " + std::to_string(loop) + " (resume with --resume)");
      return false;
    }
  }
  write_snapshot(dir_ / "archive.csv");
  finish_checkpoints();
  set_status("complete");
  return true;
}

void Run::loop_zero() {
  const auto& s = ex_.settings;
  const auto n = static_cast<std::size_t>(s.initial_samples);
  const std::size_t P = shape_.param_count();
  Parents& none = parents_;
  none.theta.resize(0, static_cast<Eigen::Index>(P));
  Offspring& off = offspring_[0];
  off.reset(n, P, 0);
  Rng rng(s.seed, Stream::kInitial, 0);
  MutateContext mctx{0, 0, &rng, repr_.get(), archive_.get()};
  initial_->mutate(none, n, mctx, off);
  if (static_cast<std::size_t>(off.theta.rows()) != n || static_cast<std::size_t>(off.theta.cols()) != P)
    throw Error("initial sampler '" + ex_.initial.type + "' returned a batch of the wrong shape");

  std::vector<std::uint64_t>& seeds = seeds_;
  seeds.resize(n);
  for (std::size_t i = 0; i < n; ++i) seeds[i] = Rng::derive_seed(s.seed, Stream::kEpisode, 0, 0, i);
  Evaluations& ev = evaluations_buffer_;
  evaluator_->evaluate(off.theta, seeds, ev);
  evaluations_ += n;
  session_evaluations_ += n;

  // Reference: the archive starts as the first-sampled policy of each distinct cell.
  std::size_t added = 0, invalid = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (ev.cells[i] < 0) {
      ++invalid;
      continue;
    }
    const auto r = archive_->offer(ev.cells[i], off.theta.row(static_cast<Eigen::Index>(i)).data(),
                                   ev.descriptors.row(static_cast<Eigen::Index>(i)).data(), ev.fitness[i], 0.0, false);
    if (r == Insertion::kAdded) ++added;
  }
  std::vector<std::size_t> slots(archive_->size());
  std::iota(slots.begin(), slots.end(), std::size_t{0});
  if (s.dataset_order == "reference")  // np.unique over one-hot rows: descending cell index
    std::sort(slots.begin(), slots.end(), [&](auto a, auto b) { return archive_->cell(a) > archive_->cell(b); });
  for (std::size_t slot : slots) dataset_->add(archive_->params(slot), archive_->cell(slot), 0);
  write_metrics_row(0, 0, &off, added, 0, invalid);
}

void Run::map_elites_loop(int loop) {
  const auto& s = ex_.settings;
  const auto batch = static_cast<std::size_t>(s.batch);
  const std::size_t P = shape_.param_count();
  const auto LD = static_cast<std::size_t>(repr_->latent_size());
  LoopContext lctx{loop, archive_.get(), dataset_.get(), repr_.get()};
  mutator_->begin_loop(lctx);

  std::vector<std::int64_t> touched;  // cells inserted or replaced this loop, first touch first
  std::vector<std::uint8_t> touched_flag(static_cast<std::size_t>(archive_->cells()), 0);
  Parents& parents = parents_;
  Vector& recn = recn_;
  // Accepted policies reach the archive's storage on a background thread (RowCopier) while the
  // next batch is evaluated; until then the archive reads them from the offspring buffer, which
  // is therefore not refilled before its copies are done. Where the evaluators leave a core free
  // the copier polls instead of being woken per batch (see RowCopier).
  const bool defer = archive_->can_defer_copies();
  if (defer && !row_copier_)
    row_copier_ = std::make_unique<RowCopier>(*archive_, evaluator_->workers() < hardware_workers());
  Evaluations& ev = evaluations_buffer_;
  std::vector<std::uint64_t>& seeds = seeds_;
  seeds.resize(batch);
  std::vector<Insertion>& outcomes = outcomes_;
  outcomes.resize(batch);
  const bool by_fitness = s.insertion == "fitness";
  // One buffer or two; archives are the same either way (see choose_one_offspring_buffer).
  const bool single_buffer = one_buffer_;
  for (int it = 0; it < s.iterations; ++it) {
    if (mutator_->uses_parents()) {
      if (archive_->size() == 0) throw Error("the archive is empty after loop 0: no initial sample could be described");
      Rng sel(s.seed, Stream::kSelection, static_cast<std::uint64_t>(loop), static_cast<std::uint64_t>(it));
      archive_->select(batch, sel, parents);
    } else {
      parents.theta.resize(0, static_cast<Eigen::Index>(P));
      parents.recn_error.resize(0);
      parents.cells.clear();
    }
    Offspring& off = offspring_[single_buffer ? 0 : (it & 1)];
    if (defer) row_copier_->wait(single_buffer ? 0 : 1);  // the buffer's earlier copies are done
    off.reset(batch, P, LD);
    Rng mrng(s.seed, Stream::kMutation, static_cast<std::uint64_t>(loop), static_cast<std::uint64_t>(it));
    MutateContext mctx{loop, it, &mrng, repr_.get(), archive_.get()};
    mutator_->mutate(parents, batch, mctx, off);
    if (static_cast<std::size_t>(off.theta.rows()) != batch || static_cast<std::size_t>(off.theta.cols()) != P ||
        off.has_latent.size() != batch || off.metrics.size() != mutator_metric_names_.size())
      throw Error("mutator '" + ex_.mutator.type + "' returned a batch of the wrong shape");
    fill_reconstruction(off, recn);

    for (std::size_t i = 0; i < batch; ++i)
      seeds[i] = Rng::derive_seed(s.seed, Stream::kEpisode, static_cast<std::uint64_t>(loop),
                                  static_cast<std::uint64_t>(it), i);

    // Sequential insertion in offspring order; the coin is drawn only for occupied cells. Rows are
    // inserted as the evaluator finishes them, which gives the same archive as inserting after the
    // batch: nothing evaluated depends on the archive.
    Rng coin(s.seed, Stream::kInsertion, static_cast<std::uint64_t>(loop), static_cast<std::uint64_t>(it));
    Feedback fb;
    fb.loop = loop;
    fb.iteration = it;
    fb.offspring = batch;
    std::size_t inserted = 0;
    auto insert_rows = [&](std::size_t end) {
      archive_->prefetch(ev.cells.data() + inserted, end - inserted);
      for (std::size_t i = inserted; i < end; ++i) {
        const std::int64_t cell = ev.cells[i];
        if (cell < 0) {
          outcomes[i] = Insertion::kInvalid;
          ++fb.invalid;
          continue;
        }
        bool replace = false;
        if (archive_->occupied(cell)) {
          if (by_fitness)
            replace = ev.fitness[i] > archive_->fitness(static_cast<std::size_t>(archive_->slot_of(cell)));
          else
            replace = coin.uniform() < s.replace_probability;
        }
        const auto e = static_cast<Eigen::Index>(i);
        outcomes[i] = defer ? archive_->offer_deferred(cell, off.theta.row(e).data(), ev.descriptors.row(e).data(),
                                                       ev.fitness[i], LD ? recn[e] : 0.0, replace, copies_)
                            : archive_->offer(cell, off.theta.row(e).data(), ev.descriptors.row(e).data(),
                                              ev.fitness[i], LD ? recn[e] : 0.0, replace);
        if (outcomes[i] == Insertion::kAdded) ++fb.added;
        if (outcomes[i] == Insertion::kReplaced) ++fb.replaced;
        if (outcomes[i] == Insertion::kRejected) ++fb.rejected;
        if ((outcomes[i] == Insertion::kAdded || outcomes[i] == Insertion::kReplaced) &&
            !touched_flag[static_cast<std::size_t>(cell)]) {
          touched_flag[static_cast<std::size_t>(cell)] = 1;
          touched.push_back(cell);
        }
      }
      inserted = end;
      if (defer && !copies_.empty()) row_copier_->submit(copies_);
    };
    if (single_buffer) {
      evaluator_->evaluate_streaming(off.theta, seeds, ev, insert_rows);
    } else {
      evaluator_->evaluate(off.theta, seeds, ev);
      insert_rows(batch);
    }
    QD_CHECK(inserted == batch, "the evaluator reported every row of the batch");
    evaluations_ += batch;
    session_evaluations_ += batch;
    fb.outcomes = &outcomes;
    mutator_->feedback(fb);
    write_metrics_row(loop, it, &off, fb.added, fb.replaced, fb.invalid);
    report(loop, it, false);
  }
  if (defer) row_copier_->wait();
  // Spec 3.3.4: the dataset gains the current occupant of every newly discovered cell.
  for (std::int64_t cell : touched)
    if (!dataset_->contains_cell(cell))
      dataset_->add(archive_->params(static_cast<std::size_t>(archive_->slot_of(cell))), cell, loop);
}

bool Run::choose_one_offspring_buffer() const {
  // One buffer: a streaming (serial) evaluator hands rows over while the batch runs, so their
  // copies into the archive are done soon after it and the next batch refills the same buffer,
  // while it is still largely in this core's L2. That pays when the buffer about fits the L2 (a
  // 2.2 MB buffer of the 32x32 arm benchmark and a 2 MB L2: qdrun 2.8 % faster than with two).
  // With a smaller L2 the buffer is evicted either way, and then the copier's reads of the rows
  // on the other core slow the refill, and the streamed parts cost a rollout call each: two
  // alternating buffers, each evaluated in one call and copied during the next batch, are faster
  // (0.9 % with a 1 MB L2, README).
  if (!archive_->can_defer_copies() || !evaluator_->streams_rows()) return false;
  const std::string& mode = ex_.settings.offspring_buffers;
  if (mode != "auto") return mode == "one";
  const std::size_t bytes = static_cast<std::size_t>(ex_.settings.batch) * shape_.param_count() * sizeof(double);
  const std::size_t l2 = core_l2_cache_bytes();
  return bytes <= l2 + l2 / 4;
}

void Run::fill_reconstruction(Offspring& off, Vector& recn) const {
  const int LD = repr_->latent_size();
  if (LD == 0) {
    recn.setZero(off.theta.rows());
    return;
  }
  std::vector<Eigen::Index> missing;
  for (std::size_t i = 0; i < off.has_latent.size(); ++i)
    if (!off.has_latent[i]) missing.push_back(static_cast<Eigen::Index>(i));
  if (!missing.empty()) {
    Matrix theta(static_cast<Eigen::Index>(missing.size()), off.theta.cols());
    for (std::size_t k = 0; k < missing.size(); ++k)
      theta.row(static_cast<Eigen::Index>(k)) = off.theta.row(missing[k]);
    Matrix z;
    repr_->encode(theta, z);
    for (std::size_t k = 0; k < missing.size(); ++k) off.latent.row(missing[k]) = z.row(static_cast<Eigen::Index>(k));
  }
  Matrix rec;
  repr_->decode(off.latent, rec);
  recn = (off.theta - rec).rowwise().norm();
}

void Run::fit_representation(int loop) {
  if (repr_->latent_size() == 0) return;
  report(loop, ex_.settings.iterations - 1, false, "training " + ex_.representation.type);
  const double t0 = now_seconds();
  FitContext fctx{loop, ex_.settings.seed, dir_.string()};
  const FitReport r = repr_->fit(*dataset_, fctx);
  const double seconds = now_seconds() - t0;
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
  append_to_file(dir_ / "training.csv", row + "\n");
  if (loop == 0) {
    // Spec 3.3.1: at loop 1 the archive is rebuilt from D with the errors of the loop-0 model.
    // Later errors stay as stored at insertion (the reference's stale values).
    Vector err;
    repr_->reconstruction_errors(Matrix(dataset_->params()), err);
    for (std::size_t k = 0; k < dataset_->size(); ++k) {
      const auto slot = archive_->slot_of(dataset_->cells()[k]);
      archive_->set_recn_error(static_cast<std::size_t>(slot), err[static_cast<Eigen::Index>(k)]);
    }
  }
}

void Run::write_metrics_row(int loop, int iteration, const Offspring* off, std::size_t added, std::size_t replaced,
                            std::size_t invalid) {
  std::string& row = metrics_row_;  // kept: no allocation per row
  row.clear();
  append_int(row, loop);
  row += ',';
  append_int(row, iteration);
  row += ',';
  append_int(row, static_cast<std::int64_t>(evaluations_));
  row += ',';
  append_int(row, static_cast<std::int64_t>(archive_->size()));
  row += ',';
  append_number(row, archive_->coverage());
  row += ',';
  if (off && !std::isnan(off->mixing_ratio)) append_number(row, off->mixing_ratio);
  row += ',';
  append_int(row, static_cast<std::int64_t>(added));
  row += ',';
  append_int(row, static_cast<std::int64_t>(replaced));
  row += ',';
  append_int(row, static_cast<std::int64_t>(invalid));
  row += ',';
  append_number(row, wall_seconds());
  row += ',';
  append_number(row, train_seconds_);
  for (std::size_t k = 0; k < mutator_metric_names_.size(); ++k) {
    row += ',';
    if (off && k < off->metrics.size()) append_number(row, off->metrics[k]);
  }
  row += '\n';
  metrics_log_.append(metrics_path_, row);
}

void Run::write_snapshot(const fs::path& path) const {
  const std::size_t P = ex_.settings.snapshot_parameters ? shape_.param_count() : 0;
  const std::size_t dims = archive_->descriptor_dims();
  // pyribs-style columns: index, objective, measures_*, solution_*; plus the stored recn error.
  std::string head = "index,objective";
  for (std::size_t d = 0; d < dims; ++d) head += ",measures_" + std::to_string(d);
  head += ",recn_error";
  for (std::size_t k = 0; k < P; ++k) head += ",solution_" + std::to_string(k);
  head += '\n';
  AtomicFile file(path);
  file.write(head);
  // Rows in cell order, so two archives with the same content give the same file.
  std::vector<std::size_t> slots(archive_->size());
  std::iota(slots.begin(), slots.end(), std::size_t{0});
  std::sort(slots.begin(), slots.end(), [&](auto a, auto b) { return archive_->cell(a) < archive_->cell(b); });
  // Pieces of about 1 MB, formatted on every core: the evaluators are idle at a loop's end.
  // A field is at most 25 characters and its separator; write_number may use more scratch.
  const std::size_t row_bytes = (3 + dims + P) * 26 + kNumberBufferBytes;
  const std::size_t rows_per_block = std::max<std::size_t>(1, (std::size_t{1} << 20) / row_bytes);
  const std::size_t blocks = (slots.size() + rows_per_block - 1) / rows_per_block;
  const Archive& archive = *archive_;
  auto format = [&](std::size_t block, char* out) {
    clear_upper_vector_state();  // once per piece: this may be a fresh thread or one after Eigen
    const std::size_t end = std::min(slots.size(), (block + 1) * rows_per_block);
    for (std::size_t r = block * rows_per_block; r < end; ++r) {
      const std::size_t slot = slots[r];
      out = std::to_chars(out, out + 24, archive.cell(slot)).ptr;
      *out++ = ',';
      out = write_number(archive.fitness(slot), out);
      const double* descriptor = archive.descriptor(slot);
      for (std::size_t d = 0; d < dims; ++d) {
        *out++ = ',';
        out = write_number(descriptor[d], out);
      }
      *out++ = ',';
      out = write_number(archive.recn_error(slot), out);
      const double* params = P ? archive.params(slot) : nullptr;
      for (std::size_t k = 0; k < P; ++k) {
        *out++ = ',';
        out = write_number(params[k], out);
      }
      *out++ = '\n';
    }
    return out;
  };
  const auto threads = static_cast<unsigned>(std::clamp(hardware_workers(), 1, 8));
  format_in_order(blocks, rows_per_block * row_bytes, threads, format,
                  [&](const char* text, std::size_t size) { file.write(text, size); });
  file.commit();
}

namespace {

// The elites of a final archive.csv: their cells and parameter rows.
struct StoredElites {
  std::vector<std::int64_t> cells;
  Matrix theta;
};

StoredElites read_archive_solutions(const fs::path& csv, std::size_t P) {
  std::ifstream in(csv);
  if (!in) throw InputError(csv.string() + ": no final archive (is the run complete?)");
  std::string header, line;
  std::getline(in, header);
  std::vector<std::string> columns;
  for (std::size_t pos = 0;;) {
    const std::size_t c = header.find(',', pos);
    columns.push_back(header.substr(pos, c == std::string::npos ? std::string::npos : c - pos));
    if (c == std::string::npos) break;
    pos = c + 1;
  }
  const auto first = std::find(columns.begin(), columns.end(), "solution_0");
  if (first == columns.end())
    throw InputError(csv.string() + ": has no solution_* columns (output.snapshot_parameters was false)");
  const auto offset = static_cast<std::size_t>(first - columns.begin());
  StoredElites out;
  std::vector<double> values;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    out.cells.push_back(std::stoll(line.substr(0, line.find(','))));
    std::size_t pos = 0;
    for (std::size_t k = 0; k < offset; ++k) pos = line.find(',', pos) + 1;
    for (std::size_t k = 0; k < P; ++k) {
      const std::size_t c = line.find(',', pos);
      values.push_back(std::stod(line.substr(pos, c - pos)));
      pos = c + 1;
    }
  }
  out.theta.resize(static_cast<Eigen::Index>(out.cells.size()), static_cast<Eigen::Index>(P));
  std::copy(values.begin(), values.end(), out.theta.data());
  return out;
}

}  // namespace

Trace Run::replay(std::int64_t cell, const fs::path& svg) const {
  const fs::path csv = dir_ / "archive.csv";
  const StoredElites elites = read_archive_solutions(csv, shape_.param_count());
  const auto it = std::find(elites.cells.begin(), elites.cells.end(), cell);
  if (it == elites.cells.end()) throw InputError(csv.string() + ": no elite in cell " + std::to_string(cell));
  Matrix theta = elites.theta.row(it - elites.cells.begin());
  std::vector<Trace> traces(1);
  const std::uint64_t seed = 0;
  RolloutBatch b{&shape_, &theta, &seed, 0, 1};
  env_->rollout(b, traces.data());
  std::ofstream out(svg);
  if (!out || !env_->draw_svg(traces[0], out))
    throw InputError("cannot draw to " + svg.string() + " (environment '" + ex_.environment.type + "')");
  return traces[0];
}

Run::ReplayAllResult Run::replay_all(const fs::path& csv) {
  const StoredElites elites = read_archive_solutions(dir_ / "archive.csv", shape_.param_count());
  const std::size_t n = elites.cells.size();
  // Seed 0 for every episode, as --replay: the environments of the paper do not use it. The
  // evaluators return compact results, so the traces are rolled out here, on local threads.
  const std::vector<std::uint64_t> seeds(n, 0);
  std::vector<Trace> traces(n);
  std::vector<std::int64_t> landed(n, -1);
  std::vector<double> values(n * archive_->descriptor_dims());
  WorkerPool pool(std::max(1, evaluator_->workers()));
  pool.run(n, [&](std::size_t i) {
    RolloutBatch b{&shape_, &elites.theta, seeds.data(), i, i + 1};
    env_->rollout(b, traces.data());
    if (traces[i].status == EvalStatus::kOk)
      desc_->describe(&traces[i], 1, &landed[i], values.data() + i * archive_->descriptor_dims());
  });
  int cols = 0;
  for (const Trace& t : traces) cols = std::max(cols, t.main.cols);
  std::string out = "cell,landed,status,row";
  for (int c = 0; c < cols; ++c) out += ",main_" + std::to_string(c);
  out += '\n';
  ReplayAllResult r;
  r.elites = n;
  for (std::size_t i = 0; i < n; ++i) {
    const Trace& t = traces[i];
    if (landed[i] == elites.cells[i]) ++r.as_stored;
    for (std::size_t row = 0; row < t.main.rows(); ++row) {
      append_int(out, elites.cells[i]);
      out += ',';
      append_int(out, landed[i]);
      out += ',';
      out += to_string(t.status);
      out += ',';
      append_int(out, static_cast<std::int64_t>(row));
      for (int c = 0; c < cols; ++c) {
        out += ',';
        if (c < t.main.cols) append_number(out, t.main.at(row, c));
      }
      out += '\n';
    }
  }
  write_file_atomic(csv, out);
  return r;
}

void Run::write_latents(const fs::path& csv) const {
  const int L = repr_->latent_size();
  if (L == 0)
    throw InputError(dir_.string() + ": [representation] type = \"" + ex_.representation.type +
                     "\" has no latent space");
  Matrix z;
  repr_->encode(Matrix(dataset_->params()), z);
  std::string out = "cell,loop";
  for (int k = 0; k < L; ++k) out += ",z_" + std::to_string(k);
  out += '\n';
  for (std::size_t i = 0; i < dataset_->size(); ++i) {
    append_int(out, dataset_->cells()[i]);
    out += ',';
    append_int(out, dataset_->loops()[i]);
    for (int k = 0; k < L; ++k) {
      out += ',';
      append_number(out, z(static_cast<Eigen::Index>(i), k));
    }
    out += '\n';
  }
  write_file_atomic(csv, out);
}

template <class T>
void append_raw(std::string& out, const T& v) {
  out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

fs::path Run::archive_log_path(std::uint64_t generation) const {
  char name[40];
  std::snprintf(name, sizeof(name), "archive-state-%05llu.bin", static_cast<unsigned long long>(generation));
  return dir_ / name;
}

void Run::write_checkpoint(int loop) {
  // Written by the background writer while the next loop runs. The archive's changed slots are
  // copied on that thread too (Archive::capture; the loop copies a slot itself only if it is about
  // to overwrite it first). Waits for the previous checkpoint first.
  if (!checkpoint_writer_) checkpoint_writer_ = std::make_unique<CheckpointWriter>();
  metrics_log_.flush();  // the checkpoint records the logs' sizes
  checkpoint_writer_->wait();
  CheckpointWriter::Job& job = checkpoint_job_;
  job.checkpoint = dir_ / kCheckpointFile;
  job.state.clear();
  job.appends.resize(2);
  job.remove_after.clear();
  for (auto& a : job.appends) a.bytes.clear();

  // The archive: an append-only log of slot records; each checkpoint appends the slots written
  // since the previous one. When more than half the log is stale, a new generation is started with
  // one record per slot and the old file is removed once the new checkpoint is committed.
  CheckpointWriter::Append& arch = job.appends[0];
  std::vector<std::size_t>& dirty = dirty_slots_;
  archive_->take_dirty(dirty);
  const std::size_t rec = archive_->record_bytes();
  const std::uint64_t header = sizeof(kArchiveLogMagic) + 2 * sizeof(std::uint64_t);
  const std::uint64_t live = header + archive_->size() * rec;
  const bool compact = archive_bytes_saved_ == 0 || archive_bytes_saved_ + dirty.size() * rec > 2 * live;
  std::vector<std::size_t>* listed = &dirty;
  if (compact) {
    if (archive_bytes_saved_ != 0) {
      job.remove_after.push_back(archive_log_path(archive_generation_));
      ++archive_generation_;
    }
    arch.path = archive_log_path(archive_generation_);
    arch.offset = 0;
    all_slots_.resize(archive_->size());
    std::iota(all_slots_.begin(), all_slots_.end(), std::size_t{0});
    listed = &all_slots_;
  } else {
    arch.path = archive_log_path(archive_generation_);
    arch.offset = archive_bytes_saved_;
  }
  // A new generation is one aligned buffer, [header | records | padding], written with O_DIRECT;
  // an append writes the records alone.
  const std::size_t capture_bytes = listed->size() * rec;
  const std::size_t align = CheckpointWriter::kDirectAlignment;
  const std::size_t padded = (header + capture_bytes + align - 1) / align * align;
  if (padded > capture_capacity_) {  // kept across checkpoints
    capture_capacity_ = std::max(padded, (capture_capacity_ + capture_capacity_ / 2 + align - 1) / align * align);
    capture_buffer_.reset(static_cast<char*>(std::aligned_alloc(align, capture_capacity_)));
    if (!capture_buffer_) throw std::bad_alloc();
  }
  char* const base = capture_buffer_.get();
  archive_->begin_capture(*listed, base + header);
  if (compact) {
    std::string head(kArchiveLogMagic, sizeof(kArchiveLogMagic));
    append_raw(head, static_cast<std::uint64_t>(shape_.param_count()));
    append_raw(head, static_cast<std::uint64_t>(archive_->descriptor_dims()));
    std::memcpy(base, head.data(), header);
    std::memset(base + header + capture_bytes, 0, padded - header - capture_bytes);
    arch.more = base;
    arch.more_size = header + capture_bytes;
    arch.direct = true;
  } else {
    arch.more = base + header;
    arch.more_size = capture_bytes;
    arch.direct = false;
  }
  job.prepare = [archive = archive_.get()] { archive->capture(); };
  archive_bytes_saved_ = arch.offset + arch.bytes.size() + arch.more_size;

  // The dataset only grows, so each checkpoint appends the rows that are new since the last one.
  CheckpointWriter::Append& data = job.appends[1];
  const std::size_t P = shape_.param_count();
  data.path = dir_ / kDatasetFile;
  data.offset = dataset_bytes_saved_;
  if (dataset_bytes_saved_ == 0) {
    data.bytes.append(kDatasetMagic, sizeof(kDatasetMagic));
    append_raw(data.bytes, static_cast<std::uint64_t>(P));
  }
  data.bytes.reserve(data.bytes.size() + (dataset_->size() - dataset_rows_saved_) * dataset_row_bytes(P));
  for (std::size_t k = dataset_rows_saved_; k < dataset_->size(); ++k) {
    append_raw(data.bytes, dataset_->cells()[k]);
    append_raw(data.bytes, static_cast<std::int64_t>(dataset_->loops()[k]));
    data.bytes.append(reinterpret_cast<const char*>(dataset_->params().row(static_cast<Eigen::Index>(k)).data()),
                      P * sizeof(double));
  }
  dataset_bytes_saved_ = data.offset + data.bytes.size();
  dataset_rows_saved_ = dataset_->size();

  {
    StringAppender sink(job.state);
    std::ostream o(&sink);
    o.write(kCheckpointMagic, sizeof(kCheckpointMagic));
    state::write_string(o, ex_.resolved_toml);
    state::write<std::int32_t>(o, loop);
    state::write<std::uint64_t>(o, evaluations_);
    state::write<double>(o, wall_seconds());
    state::write<double>(o, train_seconds_);
    // Sizes of the append-only logs, so a resume can cut away rows written after this point.
    std::vector<std::pair<std::string, std::uint64_t>> logs;
    for (const auto& e : fs::directory_iterator(dir_))
      if (e.is_regular_file() && is_appended_log(e.path()))
        logs.emplace_back(e.path().filename().string(), e.file_size());
    std::sort(logs.begin(), logs.end());
    state::write<std::uint32_t>(o, static_cast<std::uint32_t>(logs.size()));
    for (const auto& [name, size] : logs) {
      state::write_string(o, name);
      state::write<std::uint64_t>(o, size);
    }
    state::write<std::uint64_t>(o, archive_generation_);
    state::write<std::uint64_t>(o, archive_bytes_saved_);
    state::write<std::uint64_t>(o, archive_->size());
    state::write<std::uint64_t>(o, dataset_->size());
    auto blob = [&](auto& component) {
      std::string bytes;
      StringAppender b(bytes);
      std::ostream bo(&b);
      component.save(bo);
      state::write_string(o, bytes);
    };
    blob(*repr_);
    blob(*mutator_);
    blob(*initial_);
    if (!o) throw Error("cannot serialise the checkpoint");
  }
  checkpoint_writer_->submit(job);
}

void Run::finish_checkpoints() {
  if (checkpoint_writer_) checkpoint_writer_->wait();
}

void Run::load_archive(std::uint64_t generation, std::uint64_t bytes, std::uint64_t slots, bool remove_stale) {
  const fs::path path = archive_log_path(generation);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw StateError(path.string() + " is missing");
  char magic[sizeof(kArchiveLogMagic)];
  std::uint64_t P = 0, dims = 0;
  if (!in.read(magic, sizeof(magic)) || !std::equal(magic, magic + sizeof(magic), kArchiveLogMagic) ||
      !in.read(reinterpret_cast<char*>(&P), sizeof(P)) || !in.read(reinterpret_cast<char*>(&dims), sizeof(dims)))
    throw StateError(path.string() + " is not a qdrun archive state file");
  if (P != shape_.param_count() || dims != archive_->descriptor_dims())
    throw StateError(path.string() + " has another shape than this experiment");
  const std::size_t rec = archive_->record_bytes();
  const std::uint64_t header = sizeof(kArchiveLogMagic) + 2 * sizeof(std::uint64_t);
  if (bytes < header || (bytes - header) % rec != 0) throw StateError("the checkpoint's archive size is inconsistent");
  *archive_ = Archive(archive_->cells(), P, dims);
  std::vector<char> buf(rec);
  for (std::uint64_t k = 0, n = (bytes - header) / rec; k < n; ++k) {
    if (!in.read(buf.data(), static_cast<std::streamsize>(rec)))
      throw StateError(path.string() + " is shorter than the checkpoint counts");
    std::int64_t head[2];
    double values[2];
    std::memcpy(head, buf.data(), sizeof(head));
    std::memcpy(values, buf.data() + sizeof(head), sizeof(values));
    const char* desc = buf.data() + sizeof(head) + sizeof(values);
    std::vector<double> d(dims), theta(P);
    std::memcpy(d.data(), desc, dims * sizeof(double));
    std::memcpy(theta.data(), desc + dims * sizeof(double), P * sizeof(double));
    if (head[0] < 0) throw StateError(path.string() + " holds a negative slot");
    archive_->restore(static_cast<std::size_t>(head[0]), head[1], theta.data(), d.data(), values[0], values[1]);
  }
  if (archive_->size() != slots) throw StateError(path.string() + " does not hold the checkpoint's elites");
  archive_generation_ = generation;
  archive_bytes_saved_ = bytes;
  if (remove_stale) {  // generations of a compaction whose checkpoint never committed
    for (const auto& e : fs::directory_iterator(dir_)) {
      const std::string name = e.path().filename().string();
      if (name.rfind("archive-state-", 0) == 0 && e.path() != path) fs::remove(e.path());
    }
  }
}

void Run::load_dataset(std::uint64_t rows) {
  const fs::path path = dir_ / kDatasetFile;
  std::ifstream in(path, std::ios::binary);
  if (!in) throw StateError(path.string() + " is missing");
  char magic[sizeof(kDatasetMagic)];
  std::uint64_t P = 0;
  if (!in.read(magic, sizeof(magic)) || !std::equal(magic, magic + sizeof(magic), kDatasetMagic) ||
      !in.read(reinterpret_cast<char*>(&P), sizeof(P)))
    throw StateError(path.string() + " is not a qdrun dataset file");
  if (P != shape_.param_count()) throw StateError(path.string() + " has another parameter count than this experiment");
  *dataset_ = Dataset(shape_.param_count());
  std::vector<double> theta(P);
  for (std::uint64_t k = 0; k < rows; ++k) {
    std::int64_t cell = 0, loop = 0;
    if (!in.read(reinterpret_cast<char*>(&cell), sizeof(cell)) ||
        !in.read(reinterpret_cast<char*>(&loop), sizeof(loop)) ||
        !in.read(reinterpret_cast<char*>(theta.data()), static_cast<std::streamsize>(P * sizeof(double))))
      throw StateError(path.string() + " holds fewer rows than the checkpoint counts");
    if (dataset_->contains_cell(cell)) throw StateError(path.string() + " holds a cell twice");
    dataset_->add(theta.data(), cell, static_cast<int>(loop));
  }
  dataset_rows_saved_ = dataset_->size();
  dataset_bytes_saved_ = sizeof(kDatasetMagic) + sizeof(P) + rows * dataset_row_bytes(P);
}

void Run::load_checkpoint(bool cut_logs) {
  std::ifstream in(dir_ / kCheckpointFile, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  std::istringstream i(ss.str(), std::ios::binary);
  try {
    char magic[sizeof(kCheckpointMagic)];
    if (!i.read(magic, sizeof(magic)) || !std::equal(magic, magic + sizeof(magic), kCheckpointMagic))
      throw StateError("not a qdrun checkpoint");
    const std::string stored_config = state::read_string(i);
    (void)stored_config;  // the caller resolved the run directory's config.toml (with allowed overrides)
    const int loop = state::read<std::int32_t>(i);
    evaluations_ = state::read<std::uint64_t>(i);
    wall_before_ = state::read<double>(i);
    train_seconds_ = state::read<double>(i);
    const auto nlogs = state::read<std::uint32_t>(i);
    std::vector<std::pair<std::string, std::uint64_t>> logs;
    for (std::uint32_t k = 0; k < nlogs; ++k) {
      std::string name = state::read_string(i);
      logs.emplace_back(std::move(name), state::read<std::uint64_t>(i));
    }
    const auto generation = state::read<std::uint64_t>(i);
    const auto archive_bytes = state::read<std::uint64_t>(i);
    const auto archive_slots = state::read<std::uint64_t>(i);
    const auto dataset_rows = state::read<std::uint64_t>(i);
    load_archive(generation, archive_bytes, archive_slots, cut_logs);
    load_dataset(dataset_rows);
    auto blob = [&](auto& component, const char* what) {
      std::istringstream b(state::read_string(i), std::ios::binary);
      try {
        component.load(b);
      } catch (const std::exception& e) {
        throw StateError(std::string(what) + " state: " + e.what());
      }
    };
    blob(*repr_, "representation");
    blob(*mutator_, "mutator");
    blob(*initial_, "initial sampler");
    // Cut the logs back to the checkpoint and drop logs created after it.
    for (const auto& e : fs::directory_iterator(dir_)) {
      if (!cut_logs) break;
      if (!e.is_regular_file() || !is_appended_log(e.path())) continue;
      const std::string name = e.path().filename().string();
      const auto it = std::find_if(logs.begin(), logs.end(), [&](const auto& l) { return l.first == name; });
      if (it == logs.end())
        fs::remove(e.path());
      else if (e.file_size() > it->second)
        fs::resize_file(e.path(), it->second);
    }
    next_loop_ = loop + 1;
  } catch (const StateError& e) {
    throw InputError((dir_ / kCheckpointFile).string() + ": cannot resume: " + e.what());
  }
}

}  // namespace qd::runtime
