#include "trilat_proc/range_set_merger.h"

#include <gtest/gtest.h>

#include <map>

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
  // Same 16-bit number but 2 s later: another firing, with a merge of its
  // own; the old one is left to its deadline.
  m.Add(Part(3, 10 + 65536, 3'000'000, {4, 5, 6}, 3), 1'030'000, &ready);
  EXPECT_TRUE(ready.empty());
  EXPECT_EQ(m.open(), 4u);
  m.Expire(1'070'000, &ready);
  ASSERT_EQ(ready.size(), 2u);  // beacon 3's and beacon 4's firing 10
  EXPECT_EQ(ready[0].set.num_ranges, 3);
  EXPECT_EQ(ready[0].set.utime, 1'000'000);
}

// Issue #28, item 6: on a two-radio site a part of the same beacon and
// number dated 30 minutes ahead, sent between the two real parts of each
// firing, split every firing into three poses. It is another firing: the
// real parts still merge into one set of all six ranges.
TEST(RangeSetMerger, AFarDatedPartBetweenTheRealPartsDoesNotSplitTheFiring) {
  constexpr int64_t kThirtyMinutesUs = int64_t{30} * 60 * 1'000'000;
  RangeSetMerger m(SixReceivers());
  std::vector<RangeSetMerger::Ready> ready;
  for (int firing = 0; firing < 5; ++firing) {
    const int64_t t = 1'000'000 + firing * 200'000;
    m.Add(Part(3, firing, t, {1, 2, 3}, 3), t + 20'000, &ready);
    m.Add(Part(3, firing, t + kThirtyMinutesUs, {4, 5, 6}, 3), t + 21'000, &ready);
    m.Add(Part(3, firing, t + 2'000, {4, 5, 6}, 3), t + 22'000, &ready);
  }
  m.Flush(2'500'000, &ready);
  int whole = 0;
  std::map<int64_t, int> poses_per_firing_time;
  for (const RangeSetMerger::Ready& r : ready) {
    ++poses_per_firing_time[r.set.utime];
    if (r.set.num_ranges == 6) ++whole;
  }
  EXPECT_EQ(whole, 5);
  EXPECT_EQ(m.counters().at("complete"), 5);
  for (const auto& [utime, poses] : poses_per_firing_time) EXPECT_EQ(poses, 1) << utime;
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
  // Not the same firing (an impossible distance apart): each waits for its
  // own sibling, and neither joins nor releases the other.
  EXPECT_TRUE(ready.empty());
  EXPECT_EQ(m.open(), 2u);
  m.Flush(1'100'000, &ready);
  ASSERT_EQ(ready.size(), 2u);
  EXPECT_EQ(ready[0].set.num_ranges, 3);
  EXPECT_EQ(ready[1].set.num_ranges, 3);
}

}  // namespace
}  // namespace roomfix
