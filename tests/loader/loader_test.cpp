// The plugin contract, checked against deliberately broken libraries (tests/plugins).
#include "runtime/registry.hpp"

#include <qd/errors.hpp>

#include <gtest/gtest.h>

#include <boost/dll/shared_library.hpp>

#include <dlfcn.h>
#include <sys/stat.h>
#include <unistd.h>
#include <algorithm>
#include <string>
#include <vector>

using namespace qd;
using namespace qd::runtime;
namespace fs = std::filesystem;

namespace {
fs::path plugin(const std::string& name) {
  return fs::path(QD_TEST_PLUGIN_ROOT) / name / ("qd_" + name + ".so");
}

std::string load_error(Registry& reg, const fs::path& p) {
  try {
    reg.load(p);
  } catch (const PluginError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(Loader, GoodPluginRegistersItsComponents) {
  Registry reg;
  auto lib = reg.load(plugin("good"));
  EXPECT_STREQ(lib->info->plugin_version, "1.2.3");
  ASSERT_NE(reg.find("test-counted"), nullptr);
  EXPECT_EQ(reg.find("test-counted")->info->kind, Kind::kMutator);
  EXPECT_EQ(reg.find("test-fixed-latent")->info->kind, Kind::kRepresentation);
}

TEST(Loader, RejectsWrongAbiVersion) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("bad_abi"));
  EXPECT_NE(msg.find("ABI version 999"), std::string::npos) << msg;
  EXPECT_NE(msg.find("qd_bad_abi.so"), std::string::npos) << msg;
}

TEST(Loader, RejectsWrongInfoSize) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("bad_size"));
  EXPECT_NE(msg.find("plugin info size"), std::string::npos) << msg;
}

TEST(Loader, RejectsForeignBuildFingerprint) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("bad_fingerprint"));
  EXPECT_NE(msg.find("gcc-1.0"), std::string::npos) << msg;
  EXPECT_NE(msg.find("does not match the core"), std::string::npos) << msg;
}

// A plugin built with -D_GLIBCXX_DEBUG (other std:: container layouts) is refused, both
// fingerprints named.
TEST(Loader, RejectsLibraryDebugMode) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("debug_stl"));
  EXPECT_NE(msg.find("glibcxx-debug"), std::string::npos) << msg;
  EXPECT_NE(msg.find(std::string("the core's '") + qd::build_fingerprint() + "'"), std::string::npos) << msg;
}

// The fingerprint carries a hash of the public headers the core was built from.
TEST(Loader, FingerprintHashesThePublicHeaders) {
  const std::string fp = qd::build_fingerprint();
  const auto at = fp.find(";headers=");
  ASSERT_NE(at, std::string::npos) << fp;
  EXPECT_EQ(fp.substr(at + 9, 16).find_first_not_of("0123456789abcdef"), std::string::npos) << fp;
}

TEST(Loader, RejectsMissingEntrySymbol) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("no_entry"));
  EXPECT_NE(msg.find("not a qd plugin"), std::string::npos) << msg;
  EXPECT_NE(msg.find("qd_plugin_entry_v1"), std::string::npos) << msg;
}

// A plugin built with the pre-C++11 std::string ABI is refused by its fingerprint.
TEST(Loader, RejectsOldCxx11Abi) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("old_abi"));
  EXPECT_NE(msg.find("cxx11abi=0"), std::string::npos) << msg;
  EXPECT_NE(msg.find("plugin only: cxx11abi=0; core only: cxx11abi=1"), std::string::npos) << msg;
}

// Junk in a plugin directory is named with what is wrong with it, never with the I/O library's
// "basic_ios::clear: iostream error".
TEST(Loader, RejectsTextFileWithAClearReason) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("garbage"));
  EXPECT_EQ(msg, plugin("garbage").string() +
                     ": is not a shared library (no ELF header: a text file or other junk named like a plugin)");
}

TEST(Loader, RejectsEmptyFile) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("empty"));
  EXPECT_EQ(msg, plugin("empty").string() + ": is an empty file, not a shared library");
}

TEST(Loader, RejectsTruncatedElfFile) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("truncated"));
  EXPECT_NE(msg.find("qd_truncated.so: not a loadable shared library (its ELF symbol table cannot be read"),
            std::string::npos)
      << msg;
  EXPECT_EQ(msg.find("iostream"), std::string::npos) << msg;
}

// dlopen's own reason, the symbol demangled, instead of Boost's "Bad file descriptor".
TEST(Loader, RejectsMissingSymbolNamingIt) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("missing_symbol"));
  EXPECT_NE(msg.find("qd_missing_symbol.so: cannot be loaded: undefined symbol qd_test_symbol_defined_nowhere(int)"),
            std::string::npos)
      << msg;
  EXPECT_EQ(msg.find("Bad file descriptor"), std::string::npos) << msg;
}

TEST(Loader, RejectsFileNameThatDoesNotMatchPluginName) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("wrong_name"));
  EXPECT_NE(msg.find("must be named qd_other_name.so"), std::string::npos) << msg;
}

// A name an earlier library provides is left out of the later one, with a warning naming both.
TEST(Loader, DuplicateComponentAcrossLibrariesIsShadowed) {
  Registry reg;
  reg.load(plugin("good"));
  EXPECT_EQ(load_error(reg, plugin("duplicate")), "");
  EXPECT_NE(reg.find("test-counted")->plugin->path.find("qd_good.so"), std::string::npos);
  ASSERT_EQ(reg.warnings().size(), 1u);
  const std::string w = reg.warnings()[0];
  EXPECT_EQ(w, fs::weakly_canonical(plugin("duplicate")).string() + ": 'test-counted' left out, already provided by " +
                   fs::weakly_canonical(plugin("good")).string() +
                   " (first in the plugin search path wins; the library's other components stay available)");
}

// Shadowing rejects the shared name only: the shadowed library's other components stay.
TEST(Loader, ShadowingLeavesOutOnlyTheSharedName) {
  Registry reg;
  reg.add_search_dir(fs::path(QD_TEST_PLUGIN_ROOT) / "shadow");
  reg.add_search_dir(fs::path(QD_TEST_PLUGIN_ROOT) / "good");
  reg.discover();
  EXPECT_TRUE(reg.rejected().empty());
  EXPECT_NE(reg.require("test-counted", Kind::kMutator).plugin->path.find("qd_shadow.so"), std::string::npos);
  EXPECT_NE(reg.require("test-fixed-latent", Kind::kRepresentation).plugin->path.find("qd_good.so"), std::string::npos);
  ASSERT_EQ(reg.shadowed().size(), 1u);
  EXPECT_EQ(reg.shadowed()[0].name, "test-counted");
  ASSERT_EQ(reg.warnings().size(), 1u);
  EXPECT_NE(reg.warnings()[0].find("qd_good.so: 'test-counted' left out, already provided by "), std::string::npos);
  EXPECT_NE(reg.warnings()[0].find("qd_shadow.so"), std::string::npos);
}

// The case of issue 20: a user library that provides "iso" leaves the built-in library's "none",
// "uniform" and "glorot" available.
TEST(Loader, ShadowingABuiltInKeepsTheBuiltInLibrarysOtherComponents) {
  const fs::path basic = fs::path(QD_BUILD_PLUGIN_DIR_FOR_TESTS) / "qd_basic.so";
  if (!fs::exists(basic)) GTEST_SKIP() << basic << " is not built";
  Registry reg;
  reg.load(plugin("shadow"));
  reg.load(basic);
  EXPECT_NE(reg.require("iso", Kind::kMutator).plugin->path.find("qd_shadow.so"), std::string::npos);
  EXPECT_NE(reg.require("none", Kind::kRepresentation).plugin->path.find("qd_basic.so"), std::string::npos);
  EXPECT_NE(reg.require("uniform", Kind::kMutator).plugin->path.find("qd_basic.so"), std::string::npos);
  EXPECT_NE(reg.require("glorot", Kind::kMutator).plugin->path.find("qd_basic.so"), std::string::npos);
  ASSERT_EQ(reg.warnings().size(), 1u);
  EXPECT_NE(reg.warnings()[0].find("qd_basic.so: 'iso' left out, already provided by "), std::string::npos)
      << reg.warnings()[0];
}

// An unknown name is one line; a rejected library follows it only when it offers that name.
TEST(Loader, UnknownComponentErrorListsOnlyLibrariesThatCouldHaveProvidedIt) {
  Registry reg;
  for (const char* d : {"good", "garbage", "no_entry", "bad_fingerprint", "debug_stl"})
    reg.add_search_dir(fs::path(QD_TEST_PLUGIN_ROOT) / d);
  reg.discover();
  ASSERT_EQ(reg.rejected().size(), 4u);
  std::string msg;
  try {
    reg.require("no-such-thing", Kind::kMutator);
  } catch (const InputError& e) {
    msg = e.what();
  }
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  EXPECT_NE(msg.find("unknown mutator 'no-such-thing'; known mutators: test-counted; plugin search path: "),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find("(4 other rejected libraries could not have provided it; qdrun --list shows why)"),
            std::string::npos)
      << msg;
  try {
    reg.require("debug-stl-nothing", Kind::kMutator);
    msg.clear();
  } catch (const InputError& e) {
    msg = e.what();
  }
  const auto lines = std::count(msg.begin(), msg.end(), '\n');
  EXPECT_EQ(lines, 1) << msg;
  EXPECT_NE(msg.find("\n  rejected " + plugin("debug_stl").string() + ": build fingerprint '"), std::string::npos)
      << msg;
  EXPECT_NE(msg.find("(3 other rejected libraries"), std::string::npos) << msg;
}

TEST(Loader, RejectsDuplicateComponentInsideOneLibrary) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("duplicate_inside"));
  EXPECT_NE(msg.find("registered twice"), std::string::npos) << msg;
}

TEST(Loader, FactoryExceptionBecomesPluginErrorNamingComponentAndLibrary) {
  Registry reg;
  reg.load(plugin("throws"));
  const auto& e = reg.require("test-throws", Kind::kMutator);
  try {
    reg.create<Mutator>(e, Config("mutator"), BuildContext{});
    FAIL() << "expected an exception";
  } catch (const PluginError& err) {
    const std::string msg = err.what();
    EXPECT_NE(msg.find("'test-throws'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("qd_throws.so"), std::string::npos) << msg;
    EXPECT_NE(msg.find("deliberate failure in the factory"), std::string::npos) << msg;
  }
}

TEST(Loader, FactoryConfigErrorKeepsItsKey) {
  Registry reg;
  reg.load(plugin("throws"));
  const auto& e = reg.require("test-throws-config", Kind::kMutator);
  try {
    reg.create<Mutator>(e, Config("mutator"), BuildContext{});
    FAIL() << "expected an exception";
  } catch (const ConfigError& err) {
    EXPECT_EQ(err.key(), "rate");
  }
}

TEST(Loader, WrongKindIsAnActionableError) {
  Registry reg;
  reg.load(plugin("good"));
  try {
    reg.require("test-counted", Kind::kEnvironment);
    FAIL();
  } catch (const InputError& err) {
    const std::string msg = err.what();
    EXPECT_NE(msg.find("is a mutator"), std::string::npos) << msg;
  }
}

TEST(Loader, DiscoveryRecordsRejectionsAndKeepsGoodLibraries) {
  Registry reg;
  for (const char* d : {"bad_abi", "good", "no_entry", "garbage", "duplicate", "missing_symbol"})
    reg.add_search_dir(fs::path(QD_TEST_PLUGIN_ROOT) / d);
  reg.discover();
  EXPECT_NE(reg.find("test-counted"), nullptr);
  ASSERT_EQ(reg.rejected().size(), 4u);  // duplicate loads, without its shadowed name
  EXPECT_EQ(reg.plugins().size(), 2u);
  try {
    reg.require("no-such-thing", Kind::kMutator);
    FAIL();
  } catch (const InputError& err) {
    const std::string msg = err.what();
    EXPECT_NE(msg.find("unknown mutator 'no-such-thing'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("test-counted"), std::string::npos) << msg;
    // bad_abi and missing_symbol are plugins whose names could not be read: either might have it.
    EXPECT_NE(msg.find("\n  rejected " + plugin("bad_abi").string()), std::string::npos) << msg;
    EXPECT_NE(msg.find("\n  rejected " + plugin("missing_symbol").string()), std::string::npos) << msg;
    EXPECT_EQ(msg.find("qd_garbage.so"), std::string::npos) << msg;
    EXPECT_EQ(msg.find("qd_no_entry.so"), std::string::npos) << msg;
  }
}

TEST(Loader, ObjectsKeepTheirLibraryLoadedAfterTheRegistryIsGone) {
  Owned<Mutator> m;
  {
    Registry reg;
    reg.load(plugin("good"));
    m = reg.create<Mutator>(reg.require("test-counted", Kind::kMutator), Config("mutator"), BuildContext{});
  }
  // The registry and its handles are gone; the object's deleter still holds the library.
  EXPECT_TRUE(m->uses_parents());  // a virtual call into plugin code
  boost::dll::shared_library probe(plugin("good"), boost::dll::load_mode::rtld_now);
  auto live = probe.get<int()>("qd_test_live_instances");
  EXPECT_EQ(live(), 1);
  m.reset();
  EXPECT_EQ(live(), 0);
}

// Issue 32: a library whose constructor exits or crashes, whose entry symbol is null or whose
// component list points nowhere is left out by name, read in a probe process; the others stay, and
// none is loaded into this process until a component of it is constructed.
TEST(Discovery, HostileLibrariesAreRejectedByNameAndNothingIsLoadedUntilUsed) {
  Registry reg;
  reg.add_search_dir(fs::path(QD_TEST_PLUGIN_ROOT) / "hostile");
  reg.discover();
  std::vector<std::string> reasons;
  for (const auto& r : reg.rejected()) reasons.push_back(r.reason);
  ASSERT_EQ(reasons.size(), 4u) << ::testing::PrintToString(reasons);
  auto rejected = [&](const std::string& file, const std::string& why) {
    return std::any_of(reasons.begin(), reasons.end(), [&](const std::string& r) {
      return r.find(file) != std::string::npos && r.find(why) != std::string::npos;
    });
  };
  // (Under the sanitizers a crash ends in their report and abort(), an exit in a leak check.)
  EXPECT_TRUE(rejected("qd_ctor_exit.so", "ended the process while being loaded (exit("));
  EXPECT_TRUE(rejected("qd_ctor_segv.so", "crashed while being loaded (signal "));
  EXPECT_TRUE(rejected("qd_null_entry.so", "its entry symbol 'qd_plugin_entry_v1' is null"));
  EXPECT_TRUE(rejected("qd_bad_components.so", "crashed while being loaded"));
  const fs::path misspelt = fs::path(QD_TEST_PLUGIN_ROOT) / "hostile" / "qd_misspelt.so";
  const ComponentEntry& e = reg.require("misspelt", Kind::kMutator);
  ASSERT_EQ(e.info->param_count, 1u);
  EXPECT_STREQ(e.info->params[0].key, "sigma");  // read in the probe process
  EXPECT_EQ(::dlopen(misspelt.c_str(), RTLD_NOW | RTLD_NOLOAD), nullptr) << "loaded before it was used";
  Config cfg("mutator");
  cfg.set_float("sigma", 0.1);
  try {
    reg.create<Mutator>(e, cfg, BuildContext{});
    FAIL() << "the misspelt mutator was constructed";
  } catch (const ConfigError& err) {
    EXPECT_EQ(err.key(), "sigmaa");
  }
  void* handle = ::dlopen(misspelt.c_str(), RTLD_NOW | RTLD_NOLOAD);
  EXPECT_NE(handle, nullptr) << "constructing its component loads the library";
  if (handle) ::dlclose(handle);
}

// Entries named like plugins that are no library file (a dangling symlink left by a removed build,
// a symlink loop, a FIFO, a directory) are listed with what they are, never skipped without a word
// and never opened (a FIFO would block).
TEST(Discovery, EntriesThatAreNoFilesAreRejectedByName) {
  const fs::path d = fs::temp_directory_path() / ("qd_loader_entries-" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d / "qd_dir.so");
  fs::create_symlink("/nowhere/qd_gone.so", d / "qd_gone.so");
  fs::create_symlink("qd_loop.so", d / "qd_loop.so");
  ASSERT_EQ(::mkfifo((d / "qd_fifo.so").c_str(), 0644), 0);
  fs::copy_file(plugin("good"), d / "qd_good.so");
  Registry reg;
  reg.add_search_dir(d);
  reg.discover();
  EXPECT_NE(reg.find("test-counted"), nullptr);
  std::vector<std::string> reasons;
  for (const auto& r : reg.rejected()) reasons.push_back(r.reason);
  ASSERT_EQ(reasons.size(), 4u) << ::testing::PrintToString(reasons);
  for (const char* expected :
       {"qd_dir.so: a directory, not a shared library", "qd_fifo.so: a FIFO, not a shared library",
        "qd_gone.so: a symbolic link to nothing", "qd_loop.so: a symbolic link loop"}) {
    EXPECT_TRUE(std::any_of(reasons.begin(), reasons.end(),
                            [&](const std::string& r) { return r.find(expected) != std::string::npos; }))
        << expected << " in " << ::testing::PrintToString(reasons);
  }
  fs::remove_all(d);
}
