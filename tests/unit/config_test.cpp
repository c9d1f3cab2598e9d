// Configuration errors: each must name the place (file:line:column or --set) and the key. Also the
// files a run writes from a resolved configuration (archive.csv).
#include "runtime/experiment.hpp"
#include "runtime/run.hpp"

#include <qd/errors.hpp>

#include <gtest/gtest.h>

#include <unistd.h>
#include <fstream>

using namespace qd;
using namespace qd::runtime;
namespace fs = std::filesystem;

namespace {

const char* kValid = R"(
[experiment]
name = "t"
loops = 2
iterations = 2
batch = 4
initial_samples = 10

[environment]
type = "arm"

[mutator]
type = "iso"
sigma = 0.2
)";

const Registry& registry() {
  static Registry reg = [] {
    Registry r;
    r.add_search_dir(QD_BUILD_PLUGIN_DIR_FOR_TESTS);
    r.add_search_dir(fs::path(QD_TEST_PLUGIN_ROOT) / "good");
    r.discover();
    return r;
  }();
  return reg;
}

std::string error_of(const std::string& text, const std::vector<std::string>& sets = {}) {
  try {
    Document d = Document::parse(text, "exp.toml");
    for (const auto& s : sets) d.apply_override(s);
    resolve(d, registry());
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

std::string replace(std::string s, const std::string& from, const std::string& to) {
  const auto pos = s.find(from);
  EXPECT_NE(pos, std::string::npos) << from;
  return s.replace(pos, from.size(), to);
}

}  // namespace

TEST(Config, ValidFileResolvesWithDefaults) {
  Document d = Document::parse(kValid, "exp.toml");
  Experiment ex = resolve(d, registry());
  EXPECT_EQ(ex.settings.loops, 2);
  EXPECT_EQ(ex.settings.hidden, (std::vector<int>{32, 32}));
  EXPECT_EQ(ex.mutator.config.get_float("sigma"), 0.2);
  EXPECT_EQ(ex.initial.type, "uniform");
  EXPECT_EQ(ex.representation.type, "none");
  EXPECT_EQ(ex.environment.config.get_int("steps"), 50);  // a default filled in
  EXPECT_NE(ex.resolved_toml.find("steps = 50"), std::string::npos);
  EXPECT_EQ(ex.mutator.config.where("sigma"), "exp.toml:14:9");
}

TEST(Config, UnknownKeyNamesLocationAndSuggests) {
  const std::string msg = error_of(replace(kValid, "sigma = 0.2", "sgima = 0.2"));
  EXPECT_NE(msg.find("exp.toml:14:9"), std::string::npos) << msg;
  EXPECT_NE(msg.find("unknown key 'sgima' in [mutator]"), std::string::npos) << msg;
  EXPECT_NE(msg.find("did you mean 'sigma'"), std::string::npos) << msg;
}

TEST(Config, WrongTypeIsReported) {
  const std::string msg = error_of(replace(kValid, "sigma = 0.2", "sigma = \"big\""));
  EXPECT_NE(msg.find("exp.toml:14:9: mutator.sigma must be a float"), std::string::npos) << msg;
}

TEST(Config, ZeroAndNegativeBudgetsAreOutOfRange) {
  EXPECT_NE(error_of(replace(kValid, "loops = 2", "loops = 0")).find("experiment.loops = 0 is out of range"),
            std::string::npos);
  EXPECT_NE(error_of(replace(kValid, "batch = 4", "batch = -3")).find("experiment.batch = -3 is out of range"),
            std::string::npos);
  EXPECT_NE(error_of(replace(kValid, "sigma = 0.2", "sigma = -1.0")).find("mutator.sigma = -1 is out of range"),
            std::string::npos);
}

TEST(Config, UnknownComponentListsTheKnownOnes) {
  const std::string msg = error_of(replace(kValid, "type = \"iso\"", "type = \"isox\""));
  EXPECT_NE(msg.find("exp.toml:13:8"), std::string::npos) << msg;
  EXPECT_NE(msg.find("unknown mutator 'isox'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("iso, uniform"), std::string::npos) << msg;
}

TEST(Config, ComponentOfTheWrongKind) {
  const std::string msg = error_of(replace(kValid, "type = \"iso\"", "type = \"arm\""));
  EXPECT_NE(msg.find("'arm' is a environment"), std::string::npos) << msg;
}

TEST(Config, UnknownTableAndMissingMutator) {
  EXPECT_NE(
      error_of(std::string(kValid) + "\n[mutatr]\nx = 1\n").find("unknown table 'mutatr' (did you mean 'mutator'?)"),
      std::string::npos);
  const std::string msg = error_of(replace(kValid, "[mutator]\ntype = \"iso\"\nsigma = 0.2", ""));
  EXPECT_NE(msg.find("[mutator] with a type is required"), std::string::npos) << msg;
}

TEST(Config, MalformedTomlHasLineAndColumn) {
  const std::string msg = error_of("[experiment]\nseed = 1\nloops = = 2\n");
  EXPECT_NE(msg.find("exp.toml:3:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("malformed TOML"), std::string::npos) << msg;
}

TEST(Config, OverridesUseKeyPathsAndBareWords) {
  Document d = Document::parse(kValid, "exp.toml");
  d.apply_override("mutator.sigma=0.05");
  d.apply_override("mutator.type=iso");
  d.apply_override("environment.steps=7");
  Experiment ex = resolve(d, registry());
  EXPECT_EQ(ex.mutator.config.get_float("sigma"), 0.05);
  EXPECT_EQ(ex.environment.config.get_int("steps"), 7);
  const std::string msg = error_of(kValid, {"mutator.sigma=-2"});
  EXPECT_NE(msg.find("--set mutator.sigma=-2: mutator.sigma = -2 is out of range"), std::string::npos) << msg;
  EXPECT_NE(error_of(kValid, {"oops"}).find("expected KEY.PATH=VALUE"), std::string::npos);
}

TEST(Config, IncludesMergeAndTheIncludingFileWins) {
  const fs::path dir = fs::temp_directory_path() / "qd_config_include_test";
  fs::create_directories(dir / "base");
  std::ofstream(dir / "base" / "common.toml") << kValid;
  std::ofstream(dir / "exp.toml") << "include = \"base/common.toml\"\n[mutator]\nsigma = 0.3\n";
  Experiment ex = resolve(Document::read(dir / "exp.toml"), registry());
  EXPECT_EQ(ex.mutator.config.get_float("sigma"), 0.3);
  EXPECT_EQ(ex.mutator.type, "iso");
  EXPECT_EQ(ex.settings.batch, 4);
  EXPECT_NE(ex.mutator.config.where("sigma").find("exp.toml:3:"), std::string::npos);
  std::ofstream(dir / "bad.toml") << "include = \"missing.toml\"\n";
  try {
    Document::read(dir / "bad.toml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.toml: no such experiment file"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

TEST(Config, MissingFile) {
  try {
    Document::read("/nonexistent/exp.toml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/exp.toml: no such experiment file"), std::string::npos);
  }
}

TEST(Config, LatentLargerThanParameterCountIsAConfigError) {
  const std::string text = std::string(kValid) + "\n[representation]\ntype = \"test-fixed-latent\"\nlatent = 100000\n";
  Experiment ex = resolve(Document::parse(text, "exp.toml"), registry());
  try {
    qd::runtime::Run run(std::move(ex), registry(), RunOptions{});
    FAIL();
  } catch (const ConfigError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("exp.toml:"), std::string::npos) << msg;
    EXPECT_NE(msg.find("latent size 100000 is larger than the policy's parameter count 1379"), std::string::npos)
        << msg;
  }
}

// archive.csv parsed back holds every elite once, in cell order, with every number exactly as the
// archive holds it (shortest round-trip formatting; more than 200 elites of 1379 parameters).
TEST(ArchiveCsv, ParsesBackToTheArchiveInCellOrder) {
  const fs::path dir = fs::temp_directory_path() / ("qd-archive-csv-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string text = replace(replace(std::string(kValid), "loops = 2", "loops = 2\nseed = 7"),
                                   "initial_samples = 10", "initial_samples = 3000") +
                           "\n[descriptor]\ntype = \"arm-endpoint\"\nbins = 30\n";
  Experiment ex = resolve(Document::parse(text, "exp.toml"), registry());
  RunOptions opt;
  opt.directory = dir.string();
  qd::runtime::Run run(std::move(ex), registry(), std::move(opt));
  run.create_directory();
  ASSERT_TRUE(run.run());
  const qd::runtime::Archive& a = run.archive();
  const std::size_t P = a.param_count();
  ASSERT_GT(a.size(), std::size_t{200});

  std::ifstream in(dir / "archive.csv");
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  EXPECT_EQ(line.rfind("index,objective,measures_0,measures_1,recn_error,solution_0,", 0), 0u);
  std::size_t rows = 0;
  std::int64_t previous = -1;
  while (std::getline(in, line)) {
    std::vector<double> v;
    for (std::size_t pos = 0;;) {
      const std::size_t c = line.find(',', pos);
      v.push_back(std::stod(line.substr(pos, c == std::string::npos ? std::string::npos : c - pos)));
      if (c == std::string::npos) break;
      pos = c + 1;
    }
    ASSERT_EQ(v.size(), 5 + P) << "row " << rows;
    const auto cell = static_cast<std::int64_t>(v[0]);
    EXPECT_GT(cell, previous) << "rows must be in increasing cell order";
    previous = cell;
    ASSERT_TRUE(a.occupied(cell));
    const auto slot = static_cast<std::size_t>(a.slot_of(cell));
    EXPECT_EQ(v[1], a.fitness(slot));
    EXPECT_EQ(v[2], a.descriptor(slot)[0]);
    EXPECT_EQ(v[3], a.descriptor(slot)[1]);
    EXPECT_EQ(v[4], a.recn_error(slot));
    for (std::size_t k = 0; k < P; ++k) ASSERT_EQ(v[5 + k], a.params(slot)[k]) << "cell " << cell << " k " << k;
    ++rows;
  }
  EXPECT_EQ(rows, a.size());
  fs::remove_all(dir);
}
