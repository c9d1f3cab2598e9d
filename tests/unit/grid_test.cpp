// grid.toml, which plots read instead of the descriptor: written from the grid, bin labels
// included, and parsed back; a grid whose labels do not fit its bins is refused, naming the
// descriptor (runtime/components.cpp).
#include "runtime/components.hpp"

#include <qd/errors.hpp>

#include <gtest/gtest.h>
#include <toml++/toml.h>

#include <string>

using qd::GridSpec;
using qd::runtime::check_grid;
using qd::runtime::grid_toml;

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
