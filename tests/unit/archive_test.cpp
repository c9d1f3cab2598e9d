#include "runtime/grid_archive.hpp"

#include <qd/errors.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <set>
#include <sstream>
#include <thread>
#include <vector>

using namespace qd;
using qd::runtime::Archive;
using qd::runtime::Insertion;

namespace {
const double kP1[3] = {1, 2, 3}, kP2[3] = {4, 5, 6}, kD[2] = {0.5, -0.5};
}

TEST(Archive, InsertionOutcomes) {
  Archive a(10, 3, 2);
  EXPECT_EQ(a.offer(4, kP1, kD, 1.0, 0.1, false), Insertion::kAdded);
  EXPECT_EQ(a.offer(4, kP2, kD, 2.0, 0.2, false), Insertion::kRejected);
  EXPECT_EQ(a.params(0)[0], 1.0);
  EXPECT_EQ(a.offer(4, kP2, kD, 2.0, 0.2, true), Insertion::kReplaced);
  EXPECT_EQ(a.params(0)[2], 6.0);
  EXPECT_EQ(a.size(), 1u);
  EXPECT_DOUBLE_EQ(a.coverage(), 0.1);
  EXPECT_EQ(a.slot_of(4), 0);
  EXPECT_EQ(a.slot_of(3), -1);
}

TEST(Archive, SelectionWithoutReplacementWhenLargeEnough) {
  Archive a(100, 3, 2);
  for (int c = 0; c < 50; ++c) a.offer(c, kP1, kD, 0, c, false);
  Rng r(1, Stream::kSelection);
  Parents p;
  a.select(50, r, p);
  std::set<std::int64_t> cells(p.cells.begin(), p.cells.end());
  EXPECT_EQ(cells.size(), 50u);  // a permutation of all elites
  for (std::size_t i = 0; i < 50; ++i)
    EXPECT_EQ(p.recn_error[static_cast<Eigen::Index>(i)], static_cast<double>(p.cells[i]));
}

TEST(Archive, SelectionWithReplacementWhenSmall) {
  Archive a(100, 3, 2);
  for (int c = 0; c < 5; ++c) a.offer(c, kP1, kD, 0, 0, false);
  Rng r(2, Stream::kSelection);
  Parents p;
  a.select(200, r, p);
  EXPECT_EQ(p.cells.size(), 200u);
  std::set<std::int64_t> cells(p.cells.begin(), p.cells.end());
  EXPECT_EQ(cells.size(), 5u);
}

TEST(Archive, MeanReconstructionErrorOverTheElites) {
  Archive a(10, 3, 2);
  EXPECT_EQ(a.mean_recn_error(), 0.0);
  a.offer(1, kP1, kD, 0, 1.0, false);
  a.offer(7, kP2, kD, 0, 3.0, false);
  EXPECT_DOUBLE_EQ(a.mean_recn_error(), 2.0);
  a.offer(7, kP2, kD, 0, 5.0, true);  // the replacement's error counts, not the old one's
  EXPECT_DOUBLE_EQ(a.mean_recn_error(), 3.0);
  EXPECT_EQ(a.slot_of(-1), -1);
  EXPECT_EQ(a.slot_of(10), -1);
}

TEST(Archive, DirtySlotsAreTheWrittenOnesInFirstWriteOrder) {
  Archive a(10, 3, 2);
  a.offer(7, kP1, kD, 0, 0, false);  // slot 0
  a.offer(2, kP1, kD, 0, 0, false);  // slot 1
  std::vector<std::size_t> dirty;
  a.take_dirty(dirty);
  EXPECT_EQ(dirty, (std::vector<std::size_t>{0, 1}));
  a.take_dirty(dirty);
  EXPECT_TRUE(dirty.empty());
  a.offer(2, kP2, kD, 0, 0, false);  // rejected: not written
  a.offer(3, kP1, kD, 0, 0, false);  // slot 2
  a.offer(7, kP2, kD, 0, 0, true);   // slot 0 replaced
  a.offer(3, kP2, kD, 0, 0, true);   // slot 2 again: listed once
  a.set_recn_error(1, 0.5);
  a.take_dirty(dirty);
  EXPECT_EQ(dirty, (std::vector<std::size_t>{2, 0, 1}));
}

TEST(Archive, RestoreRebuildsFromRecordsAndRejectsMisfits) {
  Archive a(10, 3, 2);
  a.restore(0, 7, kP1, kD, 1.0, 0.1);
  a.restore(1, 2, kP1, kD, 2.0, 0.2);
  a.restore(0, 7, kP2, kD, 3.0, 0.3);  // a later record of slot 0 wins
  EXPECT_EQ(a.size(), 2u);
  EXPECT_EQ(a.slot_of(7), 0);
  EXPECT_EQ(a.params(0)[0], 4.0);
  EXPECT_EQ(a.fitness(0), 3.0);
  EXPECT_EQ(a.recn_error(0), 0.3);
  std::vector<std::size_t> dirty;
  a.take_dirty(dirty);
  EXPECT_TRUE(dirty.empty()) << "restored slots are already saved";
  EXPECT_THROW(a.restore(5, 4, kP1, kD, 0, 0), StateError);   // slot beyond the end
  EXPECT_THROW(a.restore(1, 3, kP1, kD, 0, 0), StateError);   // slot 1 holds cell 2
  EXPECT_THROW(a.restore(2, 7, kP1, kD, 0, 0), StateError);   // cell 7 already has slot 0
  EXPECT_THROW(a.restore(2, 10, kP1, kD, 0, 0), StateError);  // no such cell
}
