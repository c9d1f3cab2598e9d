// The plugin contract, checked against deliberately broken libraries (tests/plugins).
#include "runtime/registry.hpp"

#include <qd/errors.hpp>

#include <gtest/gtest.h>

#include <boost/dll/shared_library.hpp>

#include <string>

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

TEST(Loader, RejectsFileThatIsNotASharedLibrary) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("garbage"));
  EXPECT_NE(msg.find("not a loadable shared library"), std::string::npos) << msg;
}

TEST(Loader, RejectsFileNameThatDoesNotMatchPluginName) {
  Registry reg;
  const std::string msg = load_error(reg, plugin("wrong_name"));
  EXPECT_NE(msg.find("must be named qd_other_name.so"), std::string::npos) << msg;
}

TEST(Loader, RejectsDuplicateComponentAcrossLibraries) {
  Registry reg;
  reg.load(plugin("good"));
  const std::string msg = load_error(reg, plugin("duplicate"));
  EXPECT_NE(msg.find("'test-counted' is already provided by"), std::string::npos) << msg;
  EXPECT_NE(msg.find("qd_good.so"), std::string::npos) << msg;
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
  for (const char* d : {"bad_abi", "good", "no_entry", "garbage", "duplicate"})
    reg.add_search_dir(fs::path(QD_TEST_PLUGIN_ROOT) / d);
  reg.discover();
  EXPECT_NE(reg.find("test-counted"), nullptr);
  ASSERT_EQ(reg.rejected().size(), 4u);
  try {
    reg.require("no-such-thing", Kind::kMutator);
    FAIL();
  } catch (const InputError& err) {
    const std::string msg = err.what();
    EXPECT_NE(msg.find("unknown mutator 'no-such-thing'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("test-counted"), std::string::npos) << msg;
    EXPECT_NE(msg.find("rejected plugin libraries"), std::string::npos) << msg;
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
