#include "runtime/replay.hpp"

#include "runtime/archive_csv.hpp"
#include "runtime/number_text.hpp"
#include "runtime/run_files.hpp"
#include "runtime/worker_pool.hpp"

#include <qd/errors.hpp>

#include <algorithm>
#include <sstream>

namespace qd::runtime {
namespace fs = std::filesystem;

Trace replay_elite(const Run& run, std::int64_t cell, const fs::path& svg) {
  const Components& c = run.components();
  const fs::path csv = run.directory() / "archive.csv";
  const StoredElites elites = read_archive_solutions(csv, c.shape.param_count());
  const auto it = std::find(elites.cells.begin(), elites.cells.end(), cell);
  if (it == elites.cells.end()) throw InputError(csv.string() + ": no elite in cell " + std::to_string(cell));
  const double* theta = elites.theta.row(it - elites.cells.begin()).data();
  std::vector<Trace> traces(1);
  const std::uint64_t seed = 0;  // the paper's environments do not use episode seeds
  c.environment->rollout(RolloutBatch{&c.shape, theta, &seed, 0, 1}, traces.data());
  std::ostringstream out;
  if (!c.environment->draw_svg(traces[0], out))
    throw InputError("cannot draw to " + svg.string() + " (environment '" + run.experiment().environment.type + "')");
  write_file_atomic(svg, out.str());
  return traces[0];
}

ReplayAllResult replay_all(const Run& run, int workers, const fs::path& csv) {
  const Components& c = run.components();
  const StoredElites elites = read_archive_solutions(run.directory() / "archive.csv", c.shape.param_count());
  const std::size_t n = elites.cells.size();
  const std::size_t dims = c.grid.dims();
  // The evaluators return compact results, so the traces are rolled out here, on local threads.
  const std::vector<std::uint64_t> seeds(n, 0);
  std::vector<Trace> traces(n);
  std::vector<std::int64_t> landed(n, -1);
  std::vector<double> values(n * dims);
  WorkerPool pool(std::max(1, workers));
  pool.run(n, [&](std::size_t i) {
    c.environment->rollout(RolloutBatch{&c.shape, elites.theta.data(), seeds.data(), i, i + 1}, traces.data());
    if (traces[i].status == EvalStatus::kOk)
      c.descriptor->describe(&traces[i], 1, &landed[i], values.data() + i * dims);
  });
  int cols = 0;
  for (const Trace& t : traces) cols = std::max(cols, t.main.cols);
  std::string out = "cell,landed,status,row";
  for (int k = 0; k < cols; ++k) out += ",main_" + std::to_string(k);
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
      for (int k = 0; k < cols; ++k) {
        out += ',';
        if (k < t.main.cols) append_number(out, t.main.at(row, k));
      }
      out += '\n';
    }
  }
  write_file_atomic(csv, out);
  return r;
}

void write_latents(const Run& run, const fs::path& csv) {
  const Representation& repr = *run.components().representation;
  const Dataset& data = run.dataset();
  const int L = repr.latent_size();
  if (L == 0)
    throw InputError(run.directory().string() + ": [representation] type = \"" + run.experiment().representation.type +
                     "\" has no latent space");
  Matrix z;
  repr.encode(Matrix(data.params()), z);
  std::string out = "cell,loop";
  for (int k = 0; k < L; ++k) out += ",z_" + std::to_string(k);
  out += '\n';
  for (std::size_t i = 0; i < data.size(); ++i) {
    append_int(out, data.cells()[i]);
    out += ',';
    append_int(out, data.loops()[i]);
    for (int k = 0; k < L; ++k) {
      out += ',';
      append_number(out, z(static_cast<Eigen::Index>(i), k));
    }
    out += '\n';
  }
  write_file_atomic(csv, out);
}

}  // namespace qd::runtime
