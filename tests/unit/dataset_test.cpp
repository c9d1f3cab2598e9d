#include <qd/dataset.hpp>
#include <qd/errors.hpp>

#include <gtest/gtest.h>

#include <sstream>

using namespace qd;

TEST(Dataset, KeepsOnePolicyPerCellInInsertionOrder) {
  Dataset d(2);
  const double a[2] = {1, 2}, b[2] = {3, 4};
  d.add(a, 9, 0);
  d.add(b, 3, 1);
  EXPECT_EQ(d.size(), 2u);
  EXPECT_TRUE(d.contains_cell(9));
  EXPECT_FALSE(d.contains_cell(4));
  EXPECT_EQ(d.params()(1, 0), 3.0);
  EXPECT_EQ(d.cells()[0], 9);
  EXPECT_EQ(d.loops()[1], 1);
  std::stringstream s;
  d.save(s);
  Dataset e(2);
  e.load(s);
  EXPECT_EQ(e.size(), 2u);
  EXPECT_TRUE(e.contains_cell(3));
  EXPECT_EQ(e.params()(0, 1), 2.0);
  std::stringstream s2;
  d.save(s2);
  Dataset wrong(3);
  EXPECT_THROW(wrong.load(s2), StateError);
}
