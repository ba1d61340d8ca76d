#include "trilat_proc/range_set_merger.h"

#include <gtest/gtest.h>

namespace roomfix {
namespace {

range_set_t Part(int beacon, int64_t seq, int64_t utime, std::vector<int> receivers, int expected) {
  range_set_t s{};
  s.utime = utime;
  s.beacon_id = beacon;
  s.firing_seq = seq;
  s.speed_of_sound_mps = 343.4;
  s.num_expected = expected;
  for (int id : receivers) {
    range_t r{};
    r.receiver_id = id;
    r.range_m = id;
    s.ranges.push_back(r);
  }
  s.num_ranges = static_cast<int32_t>(s.ranges.size());
  return s;
}

RangeSetMergerOptions SixReceivers() {
  RangeSetMergerOptions o;
  o.site_receivers = 6;
  o.deadline_s = 0.05;
  return o;
}

TEST(RangeSetMerger, AWholeSetPassesAtOnceUntouched) {
  RangeSetMerger m(SixReceivers());
  std::vector<RangeSetMerger::Ready> ready;
  m.Add(Part(1, 7, 1'000'000, {1, 2, 3, 4, 5, 6}, 6), 1'010'000, &ready);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0].set.num_ranges, 6);
  EXPECT_EQ(ready[0].recv_utime, 1'010'000);
  EXPECT_EQ(m.counters().at("parts"), 0);
}

TEST(RangeSetMerger, TwoRadiosPartsOfOneFiringAreSolvedTogether) {
  RangeSetMerger m(SixReceivers());
  std::vector<RangeSetMerger::Ready> ready;
  // Radio 1 carries receivers 1-3, radio 2 receivers 4-6; each bridge
  // unwrapped the radio's 16-bit number from its own start (70000 and 4464
  // are the same firing, 70000 mod 65536), and stamped the announcement's
  // arrival on its own host, 2 ms apart.
  m.Add(Part(3, 70000, 1'000'000, {1, 2, 3}, 3), 1'020'000, &ready);
  EXPECT_TRUE(ready.empty());
  EXPECT_EQ(m.open(), 1u);
  m.Add(Part(3, 4464, 1'002'000, {4, 5, 6}, 3), 1'025'000, &ready);
  ASSERT_EQ(ready.size(), 1u);
  const range_set_t& s = ready[0].set;
  EXPECT_EQ(s.num_expected, 6);
  EXPECT_EQ(s.num_ranges, 6);
  EXPECT_EQ(s.utime, 1'000'000);   // the earlier arrival of the announcement
  EXPECT_EQ(s.firing_seq, 70000);  // the first part's count
  EXPECT_EQ(ready[0].recv_utime, 1'025'000);
  EXPECT_EQ(m.counters().at("complete"), 1);
  EXPECT_EQ(m.open(), 0u);
}

TEST(RangeSetMerger, APartWhoseSiblingIsLostIsSolvedAtTheDeadline) {
  RangeSetMerger m(SixReceivers());
  std::vector<RangeSetMerger::Ready> ready;
  m.Add(Part(3, 10, 1'000'000, {1, 2, 3}, 3), 1'020'000, &ready);
  m.Expire(1'069'999, &ready);
  EXPECT_TRUE(ready.empty());
  m.Expire(1'070'000, &ready);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0].set.num_ranges, 3);
  EXPECT_EQ(ready[0].recv_utime, 1'070'000);
  EXPECT_EQ(m.counters().at("deadline"), 1);
  // Its sibling, later still: dropped, not a second pose for the firing.
  m.Add(Part(3, 10, 1'001'000, {4, 5, 6}, 3), 1'090'000, &ready);
  EXPECT_EQ(ready.size(), 1u);
  EXPECT_EQ(m.open(), 0u);
  EXPECT_EQ(m.counters().at("late_part"), 1);
}

TEST(RangeSetMerger, DifferentFiringsAndBeaconsStayApart) {
  RangeSetMerger m(SixReceivers());
  std::vector<RangeSetMerger::Ready> ready;
  m.Add(Part(3, 10, 1'000'000, {1, 2, 3}, 3), 1'020'000, &ready);
  m.Add(Part(4, 10, 1'000'000, {4, 5, 6}, 3), 1'020'000, &ready);  // another beacon
  m.Add(Part(3, 11, 1'100'000, {4, 5, 6}, 3), 1'120'000, &ready);  // its next firing
  EXPECT_TRUE(ready.empty());
  EXPECT_EQ(m.open(), 3u);
  // Same 16-bit number but 2 s later: another firing; the old one goes.
  m.Add(Part(3, 10 + 65536, 3'000'000, {4, 5, 6}, 3), 3'020'000, &ready);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0].set.num_ranges, 3);
  EXPECT_EQ(ready[0].set.utime, 1'000'000);
}

TEST(RangeSetMerger, AReceiverInTwoPartsIsKeptOnceAndCounted) {
  RangeSetMerger m(SixReceivers());
  std::vector<RangeSetMerger::Ready> ready;
  m.Add(Part(3, 10, 1'000'000, {1, 2, 3}, 3), 1'020'000, &ready);
  m.Add(Part(3, 10, 1'000'000, {3, 4, 5}, 3), 1'021'000, &ready);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0].set.num_ranges, 5);
  EXPECT_EQ(m.counters().at("duplicate_receiver"), 1);
}

TEST(RangeSetMerger, OpenMergesAreBounded) {
  RangeSetMerger m(SixReceivers());
  std::vector<RangeSetMerger::Ready> ready;
  for (int k = 0; k < 5000; ++k)
    m.Add(Part(k % 250 + 1, k, 1'000'000, {1}, 1), 1'000'000 + k, &ready);
  EXPECT_LE(m.open(), 1024u);
  EXPECT_EQ(ready.size() + m.open(), 5000u);
}

}  // namespace
}  // namespace roomfix

namespace roomfix {
namespace {

// The two_radios layout: receivers 1-3 on radio 1, 4-6 on radio 2.
RangeSetMergerOptions TwoRadios() {
  RangeSetMergerOptions o = SixReceivers();
  for (int id : {1, 2, 3}) o.radio_of_receiver[id] = 1;
  for (int id : {4, 5, 6}) o.radio_of_receiver[id] = 2;
  return o;
}

TEST(RangeSetMerger, ARepeatedPartOfOneRadioDoesNotCompleteTheFiring) {
  RangeSetMerger m(TwoRadios());
  std::vector<RangeSetMerger::Ready> ready;
  // Radio 1's part twice (a replayed datagram, or two bridges both started
  // with --radio 1): its counts add up to the site's six, but radio 2 has
  // not spoken, so the firing stays open for radio 2's part.
  m.Add(Part(3, 10, 1'000'000, {1, 2, 3}, 3), 1'020'000, &ready);
  m.Add(Part(3, 10, 1'000'000, {1, 2}, 3), 1'021'000, &ready);
  EXPECT_TRUE(ready.empty());
  EXPECT_EQ(m.counters().at("duplicate_part"), 1);
  m.Add(Part(3, 10, 1'000'000, {4, 5, 6}, 3), 1'022'000, &ready);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0].set.num_ranges, 6);
  EXPECT_EQ(m.counters().at("complete"), 1);
}

TEST(RangeSetMerger, AHostilePartCannotGrowAMergeBeyondTheSitesReceivers) {
  RangeSetMerger m(TwoRadios());
  std::vector<RangeSetMerger::Ready> ready;
  std::vector<int> many;
  for (int id = 100; id < 356; ++id) many.push_back(id);
  // Parts naming receivers no radio carries, each a different list: every
  // one is a new part, yet the merge holds at most six ranges.
  for (int k = 0; k < 50; ++k) {
    std::vector<int> ids(many.begin() + k, many.begin() + k + 200);
    m.Add(Part(3, 10, 1'000'000, ids, 0), 1'000'000 + k, &ready);
  }
  EXPECT_TRUE(ready.empty());
  m.Flush(1'100'000, &ready);
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0].set.num_ranges, 6);
}

TEST(RangeSetMerger, AnExtremeFiringTimeIsAnotherFiringWithoutOverflow) {
  RangeSetMerger m(SixReceivers());
  std::vector<RangeSetMerger::Ready> ready;
  m.Add(Part(3, 10, INT64_MAX, {1, 2, 3}, 3), 1'000'000, &ready);
  m.Add(Part(3, 10, INT64_MIN, {4, 5, 6}, 3), 1'001'000, &ready);
  // Not the same firing (an impossible distance apart): the first is
  // released as it was, the second waits for its sibling.
  ASSERT_EQ(ready.size(), 1u);
  EXPECT_EQ(ready[0].set.num_ranges, 3);
  EXPECT_EQ(m.open(), 1u);
}

}  // namespace
}  // namespace roomfix
