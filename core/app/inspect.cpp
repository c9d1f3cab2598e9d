// qdrun --replay and --latents (inspect.hpp): open a finished run's directory, write beside it.
#include "inspect.hpp"

#include "plugin_hints.hpp"
#include "runtime/number_text.hpp"
#include "runtime/replay.hpp"
#include "runtime/run.hpp"
#include "runtime/run_files.hpp"

#include <qd/errors.hpp>

#include <cstdio>
#include <memory>

namespace qd::app {
namespace fs = std::filesystem;
using namespace qd::runtime;

namespace {

// Builds the run of an existing run directory from its own config.toml (for --replay, --latents).
void require_run_directory(const fs::path& dir) {
  if (!fs::exists(dir / "config.toml")) throw InputError(dir.string() + ": not a run directory (no config.toml)");
}

std::unique_ptr<Run> open_run_directory(const Cli& cli, const fs::path& dir, Registry& reg, int workers) {
  require_run_directory(dir);
  Document doc = Document::read(dir / "config.toml");
  setup_registry(reg, cli, doc.plugin_paths(), doc.recorded_search_path());
  RunOptions opt;
  opt.directory = dir.string();
  opt.workers = workers;
  auto run = with_plugin_hint(dir, reg, [&] { return std::make_unique<Run>(resolve(doc, reg), reg, std::move(opt)); });
  check_same_plugins(cli.quiet, *run);
  return run;
}

// What --replay and --latents write goes beside a run, never over one of its own files (the run
// could no longer be resumed): in the run directory only their own outputs or new names.
void check_output_beside_run(const fs::path& out, const fs::path& dir, const std::string& option) {
  require_run_directory(dir);
  try {
    require_replaceable(out);  // before the replay: never a device or FIFO swapped for a file
  } catch (const InputError& e) {
    throw InputError(option + " " + out.string() + ": " + e.what());
  }
  std::error_code ec;
  const fs::path parent = fs::weakly_canonical(fs::absolute(out, ec).parent_path(), ec);
  if (!fs::is_directory(parent, ec))
    throw InputError(option + " " + out.string() + ": the directory " + parent.string() + " does not exist");
  const fs::path run = fs::weakly_canonical(fs::absolute(dir, ec), ec);
  if (!fs::equivalent(parent, run, ec) && !fs::equivalent(parent, run / "archive", ec)) return;
  const std::string name = out.filename().string();
  const bool replay_output =
      name == "traces.csv" || name == "latents.csv" || (name.rfind("replay-", 0) == 0 && out.extension() == ".svg");
  bool run_file = fs::equivalent(parent, run / "archive", ec) || name.rfind("provenance", 0) == 0 ||
                  name.rfind("archive-state-", 0) == 0 || name.rfind("checkpoint.bin", 0) == 0;
  for (const char* f : {"config.toml", "grid.toml", "metrics.csv", "training.csv", "losses.csv", "pca.csv",
                        "archive.csv", "dataset.bin", "status", "lock", "qdrun.log", "fault-offspring.csv"})
    run_file = run_file || name == f;
  if (run_file || (!replay_output && exists_nofollow(out)))
    throw InputError(option + " " + out.string() + ": that is a file of the run " + dir.string() +
                     " itself; write the output elsewhere (replay and latents never change a run)");
}

// Replays run every episode in a fresh world (RolloutBatch::world = -1).
void note_fresh_worlds(const Run& run) {
  const int worlds = run.components().environment->info().persistent_worlds;
  if (worlds > 0)
    std::printf(
        "note: this environment keeps %d persistent worlds during a run (%s); a replay runs in a fresh world, "
        "so a trace can differ from the run's episode\n",
        worlds, run.components().environment_label.c_str());
}

// qdrun --replay RUN_DIR --all [--traces FILE.csv]: every elite's trajectory, for qdplot.
int replay_all(const Cli& cli) {
  if (cli.cell_given || !cli.svg.empty()) throw InputError("--replay --all takes no --cell or --svg (see --traces)");
  const fs::path dir = cli.replay;
  const fs::path csv = cli.traces.empty() ? dir / "traces.csv" : fs::path(cli.traces);
  check_output_beside_run(csv, dir, "--traces");
  Registry reg;
  const std::unique_ptr<Run> run = open_run_directory(cli, dir, reg, cli.workers);
  const ReplayAllResult r = replay_all(*run, run->workers(), csv);
  std::printf("replayed %zu elites, %zu land in their stored cell\nwrote %s\n", r.elites, r.as_stored, csv.c_str());
  note_fresh_worlds(*run);
  return 0;
}

}  // namespace

int replay(const Cli& cli) {
  if (cli.all) return replay_all(cli);
  if (!cli.cell_given) throw InputError("--replay needs --cell N (an index from archive.csv)");
  if (cli.cell < 0)
    throw InputError("--cell " + std::to_string(cli.cell) + ": a cell index is >= 0 (column 'index' of archive.csv)");
  const fs::path dir = cli.replay;
  const fs::path svg = cli.svg.empty() ? dir / ("replay-cell-" + std::to_string(cli.cell) + ".svg") : fs::path(cli.svg);
  check_output_beside_run(svg, dir, "--svg");
  Registry reg;
  const std::unique_ptr<Run> run = open_run_directory(cli, dir, reg, 1);
  const Trace t = replay_elite(*run, cli.cell, svg);
  std::int64_t cell = -1;
  const Descriptor& descriptor = *run->components().descriptor;
  std::vector<double> values(descriptor.grid().dims());
  if (t.status == EvalStatus::kOk) descriptor.describe(&t, 1, &cell, values.data());
  std::printf("replayed cell %lld: %s, %d steps, lands in cell %lld%s\nwrote %s\n", cli.cell, to_string(t.status),
              t.steps, static_cast<long long>(cell),
              cell == cli.cell ? " (as stored)" : " (differs from the stored cell)", svg.c_str());
  note_fresh_worlds(*run);
  return 0;
}

// qdrun --latents RUN_DIR [--output FILE.csv]: the dataset's latent codes under the checkpoint's
// representation, with their cells (for qdplot's latent-space figure). Reads the run, writes nothing in it
// unless FILE is there.
int latents(const Cli& cli) {
  const fs::path dir = cli.latents;
  const fs::path csv = cli.output.empty() ? dir / "latents.csv" : fs::path(cli.output);
  check_output_beside_run(csv, dir, "--output");
  Registry reg;
  const std::unique_ptr<Run> run = open_run_directory(cli, dir, reg, 1);
  run->open_for_inspection();
  write_latents(*run, csv);
  std::printf("wrote the latent codes of %zu dataset entries to %s\n", run->dataset().size(), csv.c_str());
  return 0;
}

}  // namespace qd::app
