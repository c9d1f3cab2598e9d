#include "runtime/row_copier.hpp"

#include <qd/archive.hpp>
#include <qd/errors.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <set>
#include <sstream>
#include <thread>
#include <vector>

using namespace qd;

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

// A cache hint only: empty, occupied, invalid (-1) and out-of-range cells leave the archive's
// contents, dirty marks and later outcomes as they were (out-of-range reads would trip ASan).
TEST(Archive, PrefetchChangesNothing) {
  Archive a(10, 3, 2);
  a.offer(4, kP1, kD, 1.0, 0.1, false);
  std::vector<std::size_t> dirty;
  a.take_dirty(dirty);
  std::ostringstream before;
  a.save(before);
  const std::int64_t cells[] = {4, 7, -1, 10, 1 << 30, 0};
  a.prefetch(cells, std::size(cells));
  a.prefetch(cells, 0);
  std::ostringstream after;
  a.save(after);
  EXPECT_EQ(after.str(), before.str());
  a.take_dirty(dirty);
  EXPECT_TRUE(dirty.empty());
  EXPECT_EQ(a.offer(7, kP2, kD, 2.0, 0.2, false), Insertion::kAdded);
  EXPECT_EQ(a.offer(4, kP2, kD, 2.0, 0.2, false), Insertion::kRejected);
  EXPECT_EQ(a.size(), 2u);
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

TEST(Archive, MeanReconstructionErrorAndRoundTrip) {
  Archive a(10, 3, 2);
  a.offer(1, kP1, kD, 0, 1.0, false);
  a.offer(7, kP2, kD, 0, 3.0, false);
  EXPECT_DOUBLE_EQ(a.mean_recn_error(), 2.0);
  std::stringstream s;
  a.save(s);
  Archive b(10, 3, 2);
  b.load(s);
  EXPECT_EQ(b.size(), 2u);
  EXPECT_EQ(b.slot_of(7), 1);
  EXPECT_EQ(b.params(1)[1], 5.0);
  std::stringstream s2;
  a.save(s2);
  Archive wrong(11, 3, 2);
  EXPECT_THROW(wrong.load(s2), StateError);
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

// --- Deferred copies (Archive::offer_deferred, runtime::RowCopier) ---

TEST(Archive, DeferredCopyIsReadFromItsSourceUntilReleased) {
  Archive a(10, 3, 2);
  ASSERT_TRUE(a.can_defer_copies());
  double row_a[3] = {1, 2, 3}, row_b[3] = {4, 5, 6}, row_c[3] = {7, 8, 9};
  std::vector<Archive::DeferredCopy> copies;
  EXPECT_EQ(a.offer_deferred(4, row_a, kD, 1.0, 0.0, false, copies), Insertion::kAdded);
  EXPECT_EQ(a.offer_deferred(4, row_b, kD, 2.0, 0.0, true, copies), Insertion::kReplaced);
  EXPECT_EQ(a.offer_deferred(4, row_c, kD, 3.0, 0.0, false, copies), Insertion::kRejected);
  ASSERT_EQ(copies.size(), 2u);  // no copy for a rejection
  EXPECT_EQ(a.pending_copies(), 2u);
  EXPECT_EQ(a.params(0), row_b);  // the latest accepted row, where it is
  EXPECT_EQ(a.fitness(0), 2.0);   // everything but the parameters is stored at once
  a.complete_copies({copies[0]});
  a.release_copies({copies[0]});  // row A's copy: B is still referred to
  EXPECT_EQ(a.params(0), row_b);
  EXPECT_EQ(a.pending_copies(), 1u);
  a.complete_copies({copies[1]});
  EXPECT_EQ(a.params(0), row_b);  // copied but not released: still read where it is
  a.release_copies({copies[1]});
  EXPECT_EQ(a.pending_copies(), 0u);
  EXPECT_NE(a.params(0), row_b);  // now the archive's own copy
  row_b[1] = -1.0;                // the source may be reused after its copy
  EXPECT_EQ(std::vector<double>(a.params(0), a.params(0) + 3), (std::vector<double>{4, 5, 6}));
}

// The run's patterns: two alternating offspring buffers, one batch of copies in flight while the
// next batch is made; or (a streaming evaluator) one buffer whose copies are submitted in parts as
// rows are inserted and are all done before it is refilled. Selection reads parents in between.
// Same decisions, same archive bytes, whether the copier polls or is woken, and whichever thread
// (copier or loop) copies a batch.
void expect_deferred_copies_equal_immediate_copies(bool poll, bool single_buffer = false) {
  const std::size_t P = 300, batch = 64, cells = 200;
  Archive direct(static_cast<std::int64_t>(cells), P, 2), deferred(static_cast<std::int64_t>(cells), P, 2);
  Matrix buffers[2];
  std::vector<Archive::DeferredCopy> copies;
  Rng rng(7, Stream::kPlugin);
  {
    runtime::RowCopier copier(deferred, poll);
    for (int it = 0; it < 200; ++it) {
      auto& theta = buffers[single_buffer ? 0 : (it & 1)];
      copier.wait(single_buffer ? 0 : 1);
      theta.resize(static_cast<Eigen::Index>(batch), static_cast<Eigen::Index>(P));
      rng.fill_uniform(theta.data(), static_cast<std::size_t>(theta.size()), -1.0, 1.0);
      if (deferred.size() > 0) {  // parents read while copies may be in flight
        Parents pd, pi;
        Rng s1(static_cast<std::uint64_t>(it), Stream::kSelection),
            s2(static_cast<std::uint64_t>(it), Stream::kSelection);
        deferred.select(8, s1, pd);
        direct.select(8, s2, pi);
        ASSERT_TRUE(pd.theta == pi.theta) << "iteration " << it;
      }
      for (std::size_t i = 0; i < batch; ++i) {
        const auto cell = static_cast<std::int64_t>(rng.below(cells));
        const bool replace = rng.uniform() < 0.5;
        const double* row = theta.row(static_cast<Eigen::Index>(i)).data();
        ASSERT_EQ(deferred.offer_deferred(cell, row, kD, 0.0, 0.0, replace, copies),
                  direct.offer(cell, row, kD, 0.0, 0.0, replace));
        if (single_buffer && i % 24 == 23) copier.submit(copies);  // parts of 24, 24 and 16 rows
      }
      if (!copies.empty()) copier.submit(copies);
    }
    copier.wait();
  }
  EXPECT_EQ(deferred.pending_copies(), 0u);
  std::stringstream a, b;
  direct.save(a);
  deferred.save(b);
  EXPECT_EQ(a.str(), b.str());
}

TEST(Archive, DeferredCopiesOnAPollingThreadGiveTheArchiveOfImmediateCopies) {
  expect_deferred_copies_equal_immediate_copies(true);
}

TEST(Archive, DeferredCopiesOnAWokenThreadGiveTheArchiveOfImmediateCopies) {
  expect_deferred_copies_equal_immediate_copies(false);
}

TEST(Archive, DeferredCopiesSubmittedInPartsFromOneBufferGiveTheArchiveOfImmediateCopies) {
  expect_deferred_copies_equal_immediate_copies(true, true);
}

TEST(ArchiveDeathTest, ImmediateOfferWhileCopiesArePendingAborts) {
  Archive a(10, 3, 2);
  std::vector<Archive::DeferredCopy> copies;
  a.offer_deferred(1, kP1, kD, 0.0, 0.0, false, copies);
  EXPECT_DEATH(a.offer(2, kP2, kD, 0.0, 0.0, false), "deferred copies are pending");
}

// --- Background capture for checkpoints (Archive::begin_capture / capture) ---

TEST(Archive, CaptureHoldsTheArchiveAsItWasWhenItBegan) {
  const std::size_t P = 500, cells = 300;
  Archive a(static_cast<std::int64_t>(cells), P, 2);
  std::vector<double> row(P);
  Rng rng(3, Stream::kPlugin);
  for (std::size_t c = 0; c < cells; c += 2) {
    rng.fill_uniform(row.data(), P, -1.0, 1.0);
    a.offer(static_cast<std::int64_t>(c), row.data(), kD, static_cast<double>(c), 0.0, false);
  }
  std::vector<std::size_t> slots;  // every other slot, in a shuffled order
  for (std::size_t s = 0; s < a.size(); s += 2) slots.push_back(s);
  std::reverse(slots.begin(), slots.end());
  const std::size_t rec = a.record_bytes();
  ASSERT_EQ(rec, 4 * 8 + (2 + P) * 8);
  std::vector<char> expected(slots.size() * rec), captured(slots.size() * rec);
  for (std::size_t k = 0; k < slots.size(); ++k) a.write_record(slots[k], expected.data() + k * rec);

  a.begin_capture(slots, captured.data());
  std::thread writer([&] { a.capture(); });
  // Meanwhile the loop replaces elites, adds new ones and rewrites errors.
  for (int i = 0; i < 2000; ++i) {
    rng.fill_uniform(row.data(), P, -1.0, 1.0);
    const auto cell = static_cast<std::int64_t>(rng.below(cells));
    a.offer(cell, row.data(), kD, -1.0, 0.5, true);
    if (a.size() > 0) a.set_recn_error(static_cast<std::size_t>(rng.below(a.size())), 9.0);
  }
  writer.join();
  EXPECT_EQ(captured, expected);
  std::int64_t slot0 = 0;
  std::memcpy(&slot0, captured.data(), 8);
  EXPECT_EQ(static_cast<std::size_t>(slot0), slots[0]);
}
