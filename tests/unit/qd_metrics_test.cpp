// The QD metrics of metrics.csv (qd_score, max_fitness, mean_fitness) against the archive they
// describe: known answers for qd_metrics(), the columns of a real run parsed back against its
// archive.csv, and a task without fitness leaving them empty.
#include "runtime/experiment.hpp"
#include "runtime/grid_archive.hpp"
#include "runtime/run.hpp"

#include <qd/errors.hpp>

#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

using namespace qd;
using namespace qd::runtime;
namespace fs = std::filesystem;

namespace {

const Registry& registry() {
  static Registry reg = [] {
    Registry r;
    r.add_search_dir(QD_BUILD_PLUGIN_DIR_FOR_TESTS);
    r.add_search_dir(fs::path(QD_TEST_PLUGIN_ROOT) / "fault");  // fault-arm: an environment without fitness
    r.discover();
    return r;
  }();
  return reg;
}

// A CSV file as a header and rows of fields (empty fields kept).
struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;
  std::size_t column(const std::string& name) const {
    for (std::size_t c = 0; c < header.size(); ++c)
      if (header[c] == name) return c;
    ADD_FAILURE() << "no column " << name;
    return 0;
  }
};

Csv read_csv(const fs::path& file) {
  Csv csv;
  std::ifstream in(file);
  std::string line;
  auto split = [](const std::string& l) {
    std::vector<std::string> out;
    std::stringstream ss(l);
    std::string field;
    while (std::getline(ss, field, ',')) out.push_back(field);
    if (!l.empty() && l.back() == ',') out.emplace_back();
    return out;
  };
  if (std::getline(in, line)) csv.header = split(line);
  while (std::getline(in, line)) csv.rows.push_back(split(line));
  return csv;
}

// Runs `text` to the end in a fresh directory and returns it.
fs::path run(const std::string& text, const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("qd-metrics-" + name + "-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  Experiment ex = resolve(Document::parse(text, "exp.toml"), registry());
  RunOptions opt;
  opt.directory = dir.string();
  Run r(std::move(ex), registry(), std::move(opt));
  r.create_directory();
  EXPECT_TRUE(r.run());
  return dir;
}

const char* kArm = R"(
[experiment]
seed = 3
loops = 4
iterations = 3
batch = 30
initial_samples = 200
insertion = "fitness"
[environment]
type = "arm"
fitness = "angle-variance"
[policy]
hidden = [8]
[mutator]
type = "iso"
sigma = 0.2
)";

}  // namespace

// Known answers: qd_score = sum of (fitness - bound) in slot order; max and mean over the elites.
TEST(QdMetrics, KnownAnswersForASmallArchive) {
  Archive a(10, 1, 1);
  const double p = 0.0, d = 0.0;
  for (const auto& [cell, f] : std::vector<std::pair<std::int64_t, double>>{{2, -1.5}, {7, 0.25}, {4, -3.0}})
    a.offer(cell, &p, &d, f, 0.0, false);
  const QdMetrics q = qd_metrics(a, true, -4.0);
  EXPECT_EQ(q.qd_score, 2.5 + 4.25 + 1.0);
  EXPECT_EQ(q.max_fitness, 0.25);
  EXPECT_EQ(q.mean_fitness, (-1.5 + 0.25 - 3.0) / 3.0);
  a.offer(7, &p, &d, -10.0, 0.0, true);  // a coin-flip replacement may lower the maximum
  EXPECT_EQ(qd_metrics(a, true, -4.0).max_fitness, -1.5);

  const QdMetrics no_bound = qd_metrics(a, true, std::nan(""));
  EXPECT_TRUE(std::isnan(no_bound.qd_score));
  EXPECT_EQ(no_bound.max_fitness, -1.5);
  const QdMetrics no_fitness = qd_metrics(a, false, -4.0);
  EXPECT_TRUE(std::isnan(no_fitness.qd_score) && std::isnan(no_fitness.max_fitness) &&
              std::isnan(no_fitness.mean_fitness));
  const QdMetrics empty = qd_metrics(Archive(5, 1, 1), true, 0.0);
  EXPECT_EQ(empty.qd_score, 0.0);
  EXPECT_TRUE(std::isnan(empty.max_fitness) && std::isnan(empty.mean_fitness));
}

// Every row of metrics.csv of a real run: the last one equals the sums over the final archive.csv
// (the arm's declared bound, -(dt * steps)^2 = -25 for the angle variance), and under fitness
// insertion the QD score never decreases.
TEST(QdMetrics, QdScoreEqualsTheSumOverArchiveCsv) {
  const fs::path dir = run(kArm, "arm");
  const Csv metrics = read_csv(dir / "metrics.csv"), archive = read_csv(dir / "archive.csv");
  ASSERT_EQ(metrics.rows.size(), 1u + 3u * 3u);
  ASSERT_GT(archive.rows.size(), 50u);
  const double bound = -(0.1 * 50) * (0.1 * 50);
  double sum = 0.0, best = -INFINITY;
  for (const auto& row : archive.rows) {
    const double f = std::stod(row[archive.column("objective")]);
    EXPECT_GE(f, bound);
    sum += f - bound;
    best = std::max(best, f);
  }
  const auto& last = metrics.rows.back();
  const double qd = std::stod(last[metrics.column("qd_score")]);
  EXPECT_NEAR(qd, sum, 1e-12 * std::fabs(sum));
  EXPECT_EQ(std::stod(last[metrics.column("max_fitness")]), best);
  EXPECT_NEAR(std::stod(last[metrics.column("mean_fitness")]), sum / archive.rows.size() + bound, 1e-12);
  EXPECT_EQ(std::stoul(last[metrics.column("elites")]), archive.rows.size());
  double previous = 0.0;
  for (const auto& row : metrics.rows) {
    const double v = std::stod(row[metrics.column("qd_score")]);
    EXPECT_GE(v, previous);
    previous = v;
  }
  fs::remove_all(dir);
}

// [experiment] fitness_lower_bound replaces the environment's bound.
TEST(QdMetrics, TheExperimentFilesBoundReplacesTheEnvironments) {
  std::string text = kArm;
  text.replace(text.find("insertion"), 0, "fitness_lower_bound = -100.0\n");
  const fs::path dir = run(text, "bound");
  const Csv metrics = read_csv(dir / "metrics.csv"), archive = read_csv(dir / "archive.csv");
  double sum = 0.0;
  for (const auto& row : archive.rows) sum += std::stod(row[archive.column("objective")]) + 100.0;
  EXPECT_NEAR(std::stod(metrics.rows.back()[metrics.column("qd_score")]), sum, 1e-12 * sum);
  fs::remove_all(dir);
}

// A task without fitness runs as before and leaves the three columns empty in every row; fitness
// insertion and a fitness bound are refused for it, naming the environment.
TEST(QdMetrics, TasksWithoutFitnessLeaveTheColumnsEmpty) {
  const std::string text = R"(
[experiment]
loops = 2
iterations = 2
batch = 10
initial_samples = 40
[environment]
type = "fault-arm"
[policy]
hidden = [4]
[mutator]
type = "iso"
)";
  const fs::path dir = run(text, "none");
  const Csv metrics = read_csv(dir / "metrics.csv");
  ASSERT_EQ(metrics.rows.size(), 3u);
  for (const auto& row : metrics.rows) {
    EXPECT_GT(std::stod(row[metrics.column("elites")]), 0.0);
    for (const char* name : {"qd_score", "max_fitness", "mean_fitness"})
      EXPECT_EQ(row[metrics.column(name)], "") << name;
  }
  fs::remove_all(dir);

  auto error_of = [&](const std::string& extra) {
    std::string t = text;
    t.replace(t.find("loops"), 0, extra + "\n");
    try {
      Experiment ex = resolve(Document::parse(t, "exp.toml"), registry());
      build_components(ex, registry());
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(error_of("insertion = \"fitness\"")
                .find("insertion = \"fitness\" needs a task fitness, but environment 'fault-arm' declares none"),
            std::string::npos);
  EXPECT_NE(error_of("fitness_lower_bound = 0.0")
                .find("fitness_lower_bound is set, but environment 'fault-arm' declares no fitness"),
            std::string::npos);
}
