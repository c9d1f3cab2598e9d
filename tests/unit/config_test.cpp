// Configuration errors: each must name the place (file:line:column or --set) and the key. Also the
// files a run writes from a resolved configuration (archive.csv).
#include "describe.hpp"
#include "runtime/cost_model.hpp"
#include "runtime/experiment.hpp"
#include "runtime/run.hpp"

#include <qd/errors.hpp>

#include <gtest/gtest.h>

#include <unistd.h>
#include <fstream>

using namespace qd;
using namespace qd::runtime;
using qd::app::describe_table;
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

TEST(Config, TheCostTableIsReadButIsNotPartOfTheRunsConfiguration) {
  const std::string cost = "\n[cost]\nevaluations = [0, 1000, 5000]\noffspring_time = [1.0, 1.5, 2.5]\n";
  const Document doc = Document::parse(kValid + cost, "exp.toml");
  const Experiment with = resolve(doc, registry());
  // Read by the planning wing only (--dry-run), not into the run's settings.
  const CostModel model = read_cost_model(doc);
  EXPECT_EQ(model.evaluations, (std::vector<double>{0, 1000, 5000}));
  EXPECT_EQ(model.offspring_time, (std::vector<double>{1.0, 1.5, 2.5}));
  // A run made before the table was added, or under other values, is the same run.
  EXPECT_EQ(with.resolved_toml, resolve(Document::parse(kValid, "exp.toml"), registry()).resolved_toml);
  EXPECT_TRUE(read_cost_model(Document::parse(kValid, "exp.toml")).evaluations.empty());
}

TEST(Config, AMalformedCostTableNamesTheKey) {
  const std::string lengths =
      error_of(std::string(kValid) + "\n[cost]\nevaluations = [0, 1000]\noffspring_time = [1.0, 1.5, 2.5]\n");
  EXPECT_NE(lengths.find("exp.toml:"), std::string::npos) << lengths;
  EXPECT_NE(lengths.find("cost.offspring_time has 3 values for 2 cost.evaluations"), std::string::npos) << lengths;
  const std::string order =
      error_of(std::string(kValid) + "\n[cost]\nevaluations = [0, 1000, 1000]\noffspring_time = [1.0, 1.5, 2.5]\n");
  EXPECT_NE(order.find("cost.evaluations must increase (entry 3 is not above entry 2)"), std::string::npos) << order;
  EXPECT_NE(
      error_of(std::string(kValid) + "\n[cost]\nevaluations = [0]\noffspring_time = [0.0]\n").find("out of range"),
      std::string::npos);
  const std::string typo = error_of(std::string(kValid) + "\n[cost]\noffspring_times = [1.0]\n");
  EXPECT_NE(typo.find("unknown key 'offspring_times' in [cost]"), std::string::npos) << typo;
  const std::string cells = error_of(std::string(kValid) + "\n[cost]\nevaluations = [0, 1000]\ncells = [10]\n");
  EXPECT_NE(cells.find("cost.cells has 1 values for 2 cost.evaluations"), std::string::npos) << cells;
  const std::string bare = error_of(std::string(kValid) + "\n[cost]\nevaluations = [0, 1000]\n");
  EXPECT_NE(bare.find("give cost.offspring_time, cost.cells or both"), std::string::npos) << bare;
  EXPECT_NE(error_of(std::string(kValid) + "\n[cost]\nevaluations = [0]\ncells = [-1]\n").find("out of range"),
            std::string::npos);
}

TEST(Config, TheCostTableMayGiveCellsWithoutTimes) {
  const CostModel m = read_cost_model(
      Document::parse(std::string(kValid) + "\n[cost]\nevaluations = [0, 1000]\ncells = [0, 40]\n", "exp.toml"));
  EXPECT_EQ(m.cells, (std::vector<double>{0, 40}));
  EXPECT_TRUE(m.offspring_time.empty());
  EXPECT_EQ(m.offspring_time_at(500), 1.0);  // episodes priced by the pilot's offspring
  EXPECT_DOUBLE_EQ(m.cells_at(250), 10.0);
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

// An include cycle is named with the files that make it, not followed until a depth limit; one file
// included twice without a cycle (a diamond) is fine.
TEST(Config, IncludeCycleIsNamedAndADiamondIsNoCycle) {
  const fs::path dir = fs::temp_directory_path() / "qd_config_include_cycle_test";
  fs::create_directories(dir);
  std::ofstream(dir / "a.toml") << "include = \"b.toml\"\n";
  std::ofstream(dir / "b.toml") << "include = \"sub/../a.toml\"\n";
  fs::create_directories(dir / "sub");
  try {
    Document::read(dir / "a.toml");
    FAIL();
  } catch (const InputError& e) {
    const std::string what = e.what();
    const std::string a = fs::canonical(dir / "a.toml").string(), b = fs::canonical(dir / "b.toml").string();
    EXPECT_NE(what.find(": an include cycle (" + a + " -> " + b + " -> " + a + ")"), std::string::npos) << what;
    EXPECT_EQ(what.find("(included from", what.find("(included from") + 1), what.rfind("(included from")) << what;
  }
  std::ofstream(dir / "base.toml") << kValid;
  std::ofstream(dir / "left.toml") << "include = \"base.toml\"\n";
  std::ofstream(dir / "right.toml") << "include = \"base.toml\"\n[mutator]\nsigma = 0.4\n";
  std::ofstream(dir / "top.toml") << "include = [\"left.toml\", \"right.toml\"]\n";
  EXPECT_EQ(resolve(Document::read(dir / "top.toml"), registry()).mutator.config.get_float("sigma"), 0.4);
  fs::remove_all(dir);
}

// Bare words are strings (nan, inf and dates included); numbers stay numbers, true/false booleans.
TEST(Config, OverrideValuesAreTypedAsDocumented) {
  auto resolved = [](const std::vector<std::string>& sets) {
    Document d = Document::parse(kValid, "exp.toml");
    for (const auto& s : sets) d.apply_override(s);
    return resolve(d, registry());
  };
  EXPECT_EQ(resolved({"experiment.name=nan"}).settings.name, "nan");
  EXPECT_EQ(resolved({"experiment.name=inf"}).settings.name, "inf");
  EXPECT_EQ(resolved({"experiment.name=-inf"}).settings.name, "-inf");
  EXPECT_EQ(resolved({"experiment.name=2024-01-01"}).settings.name, "2024-01-01");
  EXPECT_EQ(resolved({"experiment.name=\"12\""}).settings.name, "12");
  const Experiment ex = resolved({"experiment.seed=12", "output.snapshot_parameters=false", "mutator.sigma=1e-2"});
  EXPECT_EQ(ex.settings.seed, 12u);
  EXPECT_FALSE(ex.settings.snapshot_parameters);
  EXPECT_EQ(ex.mutator.config.get_float("sigma"), 0.01);
  // A word where a number belongs is a type error naming the key, not a NaN.
  EXPECT_NE(error_of(kValid, {"mutator.sigma=nan"}).find("--set mutator.sigma=nan: mutator.sigma must be a float"),
            std::string::npos)
      << error_of(kValid, {"mutator.sigma=nan"});
}

// --set mutator.type=... over a file with other mutator keys: the keys the new component does not
// declare are dropped with a note; those it declares are kept.
TEST(Config, ReplacingTheTypeWithSetDropsUndeclaredKeys) {
  Document d = Document::parse(kValid, "exp.toml");
  d.apply_override("mutator.type=uniform");
  const Experiment ex = resolve(d, registry());
  EXPECT_EQ(ex.mutator.type, "uniform");
  ASSERT_EQ(ex.notes.size(), 1u);
  EXPECT_EQ(ex.notes[0],
            "[mutator] type = \"uniform\" (--set mutator.type=uniform) replaces \"iso\": dropped sigma "
            "(exp.toml:14:9), which uniform does not declare");
  EXPECT_EQ(ex.resolved_toml.find("sigma"), std::string::npos) << ex.resolved_toml;

  Document kept = Document::parse(kValid, "exp.toml");
  kept.apply_override("mutator.type=poms");
  const Experiment poms = resolve(kept, registry());
  EXPECT_TRUE(poms.notes.empty());
  EXPECT_EQ(poms.mutator.config.get_float("sigma"), 0.2);

  // A key given on the command line is the user's: checked against the new component.
  const std::string msg = error_of(kValid, {"mutator.sigma=0.3", "mutator.type=uniform"});
  EXPECT_NE(msg.find("--set mutator.sigma=0.3: unknown key 'sigma' in [mutator]"), std::string::npos) << msg;
}

// The same through include; keys of the including file are still checked, typos stay errors.
TEST(Config, ReplacingTheTypeThroughIncludeDropsUndeclaredKeys) {
  const fs::path dir = fs::temp_directory_path() / ("qd_config_swap_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "base.toml") << kValid;
  std::ofstream(dir / "mid.toml") << "include = \"base.toml\"\n[mutator]\nsigma = 0.5\n";
  std::ofstream(dir / "exp.toml") << "include = \"mid.toml\"\n[mutator]\ntype = \"glorot\"\n";
  const Experiment ex = resolve(Document::read(dir / "exp.toml"), registry());
  EXPECT_EQ(ex.mutator.type, "glorot");
  ASSERT_EQ(ex.notes.size(), 1u);
  EXPECT_NE(ex.notes[0].find("[mutator] type = \"glorot\" (" + (dir / "exp.toml").string() +
                             ":3:8) replaces \"iso\": dropped sigma (" + (dir / "mid.toml").string() + ":3:9)"),
            std::string::npos)
      << ex.notes[0];
  std::ofstream(dir / "typo.toml") << "include = \"base.toml\"\n[mutator]\ntype = \"glorot\"\nsgima = 1.0\n";
  try {
    resolve(Document::read(dir / "typo.toml"), registry());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("typo.toml:4:9: unknown key 'sgima' in [mutator]"), std::string::npos)
        << e.what();
  }
  fs::remove_all(dir);
}

// config.toml records the user's plugin directories, and reading it back gives them.
TEST(Config, ResolvedConfigurationRecordsThePluginSearchPath) {
  const Experiment ex = resolve(Document::parse(kValid, "exp.toml"), registry());
  const Document back = Document::parse(ex.resolved_toml, "config.toml");
  const std::vector<std::string> recorded = back.recorded_search_path();
  ASSERT_EQ(recorded.size(), 2u) << ex.resolved_toml;
  EXPECT_EQ(recorded[0], fs::weakly_canonical(QD_BUILD_PLUGIN_DIR_FOR_TESTS).string());
  EXPECT_EQ(recorded[1], fs::weakly_canonical(fs::path(QD_TEST_PLUGIN_ROOT) / "good").string());
  EXPECT_TRUE(fs::path(recorded[0]).is_absolute());
  EXPECT_TRUE(back.plugin_paths().empty());
  // It is read back without complaint, and an unknown [plugins] key is still an error.
  EXPECT_NO_THROW(resolve(back, registry()));
  EXPECT_NE(error_of(std::string(kValid) + "\n[plugins]\nsearch = [\"x\"]\n").find("unknown key 'search' in [plugins]"),
            std::string::npos);
}

// qdrun --describe covers the tables that are no plain parameter list.
TEST(Config, DescribeCoversPluginsAndTheComponentTables) {
  const std::string initial = describe_table("initial", registry());
  EXPECT_NE(initial.find("[initial] (core): the loop-0 sampler"), std::string::npos) << initial;
  EXPECT_NE(initial.find("type (string, default \"uniform\")"), std::string::npos) << initial;
  EXPECT_NE(initial.find("available: "), std::string::npos) << initial;
  EXPECT_NE(initial.find("glorot"), std::string::npos) << initial;
  EXPECT_NE(describe_table("mutator", registry()).find("type (string, required)"), std::string::npos);
  EXPECT_NE(describe_table("descriptor", registry()).find("the environment's own descriptor"), std::string::npos);
  const std::string plugins = describe_table("plugins", registry());
  EXPECT_NE(plugins.find("  path (list of strings"), std::string::npos) << plugins;
  EXPECT_NE(plugins.find("  search_path (list of strings, written by qdrun)"), std::string::npos) << plugins;
  EXPECT_EQ(describe_table("experiment", registry()), "");  // a plain parameter table: core_tables()
  EXPECT_EQ(describe_table("iso", registry()), "");
}

TEST(Config, MissingFile) {
  try {
    Document::read("/nonexistent/exp.toml");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/exp.toml: no such experiment file"), std::string::npos);
  }
}

// Settings that select a behaviour are enums from validation on; an unknown word is refused at its
// place, with the key and the words it may be.
TEST(Config, BehaviourSettingsAreTypedOnceAndRefuseUnknownWords) {
  const std::string text = replace(kValid, "initial_samples = 10",
                                   "initial_samples = 10\ninsertion = \"fitness\"\ndataset_order = \"insertion\"") +
                           "\n[evaluation]\nbackend = \"threads\"\n";
  const Experiment ex = resolve(Document::parse(text, "exp.toml"), registry());
  EXPECT_EQ(ex.settings.insertion, InsertionRule::kFitness);
  EXPECT_EQ(ex.settings.dataset_order, DatasetOrder::kInsertion);
  EXPECT_EQ(ex.settings.backend, Backend::kThreads);
  // The defaults, and the words the enums stand for are the schema's choices, in order.
  const Experiment d = resolve(Document::parse(kValid, "exp.toml"), registry());
  EXPECT_EQ(d.settings.insertion, InsertionRule::kCoinFlip);
  EXPECT_EQ(d.settings.dataset_order, DatasetOrder::kReference);
  EXPECT_EQ(d.settings.backend, Backend::kAuto);
  auto choices = [](const char* table, const char* key) {
    for (const CoreTable& t : core_tables())
      for (std::size_t i = 0; t.name == std::string(table) && i < t.count; ++i)
        if (t.params[i].key == std::string(key)) return std::string(t.params[i].choices);
    return std::string();
  };
  EXPECT_EQ(choices("experiment", "insertion"),
            std::string(to_string(InsertionRule::kCoinFlip)) + "|" + to_string(InsertionRule::kFitness));
  EXPECT_EQ(choices("experiment", "dataset_order"),
            std::string(to_string(DatasetOrder::kReference)) + "|" + to_string(DatasetOrder::kInsertion));
  EXPECT_EQ(choices("evaluation", "backend"), std::string(to_string(Backend::kAuto)) + "|" +
                                                  to_string(Backend::kThreads) + "|" + to_string(Backend::kProcesses) +
                                                  "|" + to_string(Backend::kMpi));

  const std::string msg =
      error_of(replace(kValid, "initial_samples = 10", "initial_samples = 10\ninsertion = \"fitnes\""));
  EXPECT_NE(msg.find("exp.toml:8:13: experiment.insertion = \"fitnes\" is not one of: coin-flip, fitness (did you "
                     "mean 'fitness'?)"),
            std::string::npos)
      << msg;
  const std::string set = error_of(kValid, {"evaluation.backend=thread"});
  EXPECT_NE(set.find("--set evaluation.backend=thread: evaluation.backend = \"thread\" is not one of: auto, threads, "
                     "processes, mpi"),
            std::string::npos)
      << set;
}

// A value set through the document arrives as that string, whatever it holds: quotes, backslashes
// and newlines are quoted once, by toml_string (a sweep's --output, a run directory's output.dir).
TEST(Config, StringsSetThroughTheDocumentRoundTrip) {
  const std::string tricky = "it's \"quoted\" \\ and = and # and [x]";
  Document d = Document::parse(kValid, "exp.toml");
  d.set_string("experiment.name", tricky);
  d.set_integer("experiment.seed", 9000000000000000);
  const Experiment ex = resolve(d, registry());
  EXPECT_EQ(ex.settings.name, tricky);
  EXPECT_EQ(ex.settings.seed, 9000000000000000u);
  // ... and back through the resolved configuration, as --resume reads config.toml.
  EXPECT_EQ(config_values(ex.resolved_toml, "config.toml").at("experiment.name"), toml_string(tricky));
  EXPECT_EQ(resolve(Document::parse(ex.resolved_toml, "config.toml"), registry()).settings.name, tricky);

  Document nl = Document::parse(kValid, "exp.toml");
  nl.set_string("output.dir", "runs\nelsewhere");  // arrives whole, and is refused by the schema
  try {
    resolve(nl, registry());
    FAIL();
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("--set output.dir=\"runs\\nelsewhere\": output.dir contains a control character "
                       "(runs\\nelsewhere)"),
              std::string::npos)
        << msg;
  }
}

// The environment's default descriptor comes from its component info: resolve() fills it in with
// no plugin object built, after the other tables (where config.toml has always had it).
TEST(Config, TheDefaultDescriptorIsResolvedFromTheEnvironmentsComponentInfo) {
  const Experiment ex = resolve(Document::parse(kValid, "exp.toml"), registry());
  EXPECT_EQ(ex.descriptor.type, "arm-endpoint");
  ASSERT_NE(ex.descriptor.entry, nullptr);
  EXPECT_TRUE(ex.descriptor.implied);
  EXPECT_EQ(ex.descriptor.config.get_int("bins"), 50);                             // its default
  const std::string table = "\n[descriptor]\nbins = 50\ntype = 'arm-endpoint'\n";  // the last table
  ASSERT_GE(ex.resolved_toml.size(), table.size());
  EXPECT_EQ(ex.resolved_toml.substr(ex.resolved_toml.size() - table.size()), table) << ex.resolved_toml;
  // Each environment of this repository declares its own.
  for (const auto& [env, descriptor] :
       std::vector<std::pair<std::string, std::string>>{{"arm", "arm-endpoint"},
                                                        {"striker", "striker-contacts"},
                                                        {"bipedal-walker", "walker-gait"},
                                                        {"bipedal-kicker", "kicker-ball"},
                                                        {"lp-sphere", "lp-measures"},
                                                        {"lp-rastrigin", "lp-measures"}}) {
    const ComponentEntry* e = registry().find(env);
    ASSERT_NE(e, nullptr) << env;
    ASSERT_NE(e->info->default_descriptor, nullptr) << env;
    EXPECT_EQ(e->info->default_descriptor, descriptor) << env;
  }
  EXPECT_EQ(registry().find("iso")->info->default_descriptor, nullptr);
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
