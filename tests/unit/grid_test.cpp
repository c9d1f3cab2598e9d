// grid.toml, which plots read instead of the descriptor: written from the grid, bin labels
// included, and parsed back; a grid whose labels do not fit its bins is refused, naming the
// descriptor (runtime/components.cpp). A run's stored grid and CVT centroids are read back only
// from regular files of the run directory.
#include "runtime/components.hpp"
#include "runtime/run_files.hpp"

#include <qd/errors.hpp>

#include <gtest/gtest.h>
#include <toml++/toml.h>

#include <sys/stat.h>
#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <string>

using qd::GridSpec;
using qd::runtime::check_grid;
using qd::runtime::grid_toml;
using qd::runtime::read_stored_grid;
namespace fs = std::filesystem;

namespace {
GridSpec three_by_two() {
  GridSpec g;
  g.shape = {3, 2};
  g.names = {"side", "height"};
  g.lower = {0.0, -1.0};
  g.upper = {3.0, 1.0};
  g.cells = 6;
  return g;
}

std::string refusal(const GridSpec& g) {
  try {
    check_grid(g, "descriptor 'd' (/lib/qd_d.so)");
  } catch (const qd::PluginError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(GridToml, RoundTripsWithBinLabels) {
  GridSpec g = three_by_two();
  g.labels = {{"left", "still", "right \"fast\""}, {}};
  const toml::table t = toml::parse(grid_toml(g));
  EXPECT_EQ(t["cells"].value<std::int64_t>(), 6);
  EXPECT_EQ(t["names"][1].value<std::string>(), "height");
  EXPECT_EQ(t["lower"][1].value<double>(), -1.0);
  const toml::array& labels = *t["labels"].as_array();
  ASSERT_EQ(labels.size(), 2u);
  EXPECT_EQ(labels[0].as_array()->size(), 3u);
  EXPECT_EQ(t["labels"][0][2].value<std::string>(), "right \"fast\"");
  EXPECT_TRUE(labels[1].as_array()->empty());
  EXPECT_EQ(refusal(g), "");
}

TEST(GridToml, NoLabelsNoKey) {
  const toml::table t = toml::parse(grid_toml(three_by_two()));
  EXPECT_FALSE(t.contains("labels"));
}

TEST(GridToml, LabelsThatDoNotFitTheBinsAreRefused) {
  GridSpec g = three_by_two();
  g.labels = {{"left", "right"}, {}};
  EXPECT_EQ(refusal(g),
            "descriptor 'd' (/lib/qd_d.so) declares 2 bin labels for dimension 0 ('side'), which has 3 bins");
  g.labels = {{"left", "still", "right"}};
  EXPECT_EQ(refusal(g), "descriptor 'd' (/lib/qd_d.so) declares bin labels for 1 dimensions of a 2-dimensional grid");
  g = three_by_two();
  g.cells = 7;
  EXPECT_EQ(refusal(g), "descriptor 'd' (/lib/qd_d.so) declares 7 cells, but its shape has 6");
}

namespace {
std::string read_refusal(const fs::path& dir) {
  GridSpec g;
  try {
    read_stored_grid(dir, g);
  } catch (const qd::StateError& e) {
    return e.what();
  }
  return "";
}
}  // namespace

// grid.toml and centroids.csv are state of the run: a FIFO or a symlink to a device there would
// block or never end, and grid.toml may name no file outside the run directory. A run whose
// stored grid reads back gets exactly its centroids.
TEST(StoredGrid, CentroidsAreReadOnlyFromRegularFilesOfTheRun) {
  const fs::path d = fs::temp_directory_path() / ("qd_grid_test-" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  GridSpec g;
  g.shape = {3};
  g.names = {"x", "y"};
  g.lower = {0.0, 0.0};
  g.upper = {1.0, 1.0};
  g.cells = 3;
  g.centroids = {0.1, 0.2, 0.5, 0.25, 0.9, 0.75};
  qd::runtime::write_file_atomic(d / "centroids.csv", qd::runtime::centroids_csv(g));
  qd::runtime::write_file_atomic(d / "grid.toml", grid_toml(g));
  GridSpec back;
  ASSERT_TRUE(read_stored_grid(d, back));
  EXPECT_EQ(back.centroids, g.centroids);

  fs::rename(d / "centroids.csv", d / "kept.csv");
  ASSERT_EQ(::mkfifo((d / "centroids.csv").c_str(), 0644), 0);  // no writer: a plain open would block
  EXPECT_NE(read_refusal(d).find("centroids.csv is a FIFO, not a regular file"), std::string::npos);
  fs::remove(d / "centroids.csv");
  fs::create_symlink("/dev/zero", d / "centroids.csv");
  EXPECT_NE(read_refusal(d).find("centroids.csv is a symbolic link"), std::string::npos);
  fs::remove(d / "centroids.csv");
  EXPECT_NE(read_refusal(d).find("centroids.csv is missing"), std::string::npos);
  fs::rename(d / "kept.csv", d / "centroids.csv");

  std::string toml = grid_toml(g);
  const std::string named = "centroids = \"centroids.csv\"";
  ASSERT_NE(toml.find(named), std::string::npos);
  for (const char* elsewhere : {"/dev/zero", "../centroids.csv", ".."}) {
    std::string edited = toml;
    edited.replace(edited.find(named), named.size(), "centroids = \"" + std::string(elsewhere) + "\"");
    std::ofstream(d / "grid.toml") << edited;
    EXPECT_NE(read_refusal(d).find("which is no file of the run directory"), std::string::npos) << elsewhere;
  }
  fs::remove(d / "grid.toml");
  ASSERT_EQ(::mkfifo((d / "grid.toml").c_str(), 0644), 0);
  EXPECT_NE(read_refusal(d).find("grid.toml is a FIFO, not a regular file"), std::string::npos);
  fs::remove_all(d);
}
