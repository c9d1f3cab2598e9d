#include <qd/dataset.hpp>

#include <gtest/gtest.h>

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
}
