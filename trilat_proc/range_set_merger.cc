#include "trilat_proc/range_set_merger.h"

#include <algorithm>
#include <cstdlib>

#include "msgio/time_limits.h"

namespace roomfix {

bool RangeSetMergerOptions::IsValid(std::string* error) const {
  if (!(deadline_s > 0.0 && deadline_s <= 10.0)) {
    *error = "merge deadline must be in (0, 10] s";
    return false;
  }
  if (!(same_firing_s > 0.0 && same_firing_s <= 60.0)) {
    *error = "same-firing window must be in (0, 60] s";
    return false;
  }
  if (site_receivers < 1) {
    *error = "the site must have receivers";
    return false;
  }
  return true;
}

RangeSetMerger::RangeSetMerger(const RangeSetMergerOptions& options) : options_(options) {
  for (const char* name :
       {"parts", "complete", "deadline", "duplicate_receiver", "late_part", "duplicate_part"}) {
    counters_[name] = 0;
  }
}

void RangeSetMerger::Release(OpenMap::iterator it, int64_t recv_utime, const char* why,
                             std::vector<Ready>* ready) {
  ++counters_[why];
  released_.push_back({it->first, it->second.set.utime});
  if (released_.size() > kMaxReleased) released_.pop_front();
  it->second.set.num_ranges = static_cast<int32_t>(it->second.set.ranges.size());
  ready->push_back({std::move(it->second.set), recv_utime});
  open_.erase(it);
}

std::vector<int32_t> RangeSetMerger::PartSignature(const range_set_t& set) const {
  std::vector<int32_t> signature;
  if (!options_.radio_of_receiver.empty()) {
    // A bridge run with --radio reports only its radio's receivers; a part
    // that mixes radios (or names receivers no radio carries) is signed by
    // all the radios it names, so it still cannot repeat a part.
    for (const range_t& r : set.ranges) {
      const auto radio = options_.radio_of_receiver.find(r.receiver_id);
      signature.push_back(radio == options_.radio_of_receiver.end() ? -1 - r.receiver_id
                                                                    : radio->second);
    }
  } else {
    for (const range_t& r : set.ranges) signature.push_back(r.receiver_id);
  }
  std::sort(signature.begin(), signature.end());
  signature.erase(std::unique(signature.begin(), signature.end()), signature.end());
  return signature;
}

void RangeSetMerger::Merge(const range_set_t& set, Open* open) {
  range_set_t& merged = open->set;
  for (const range_t& r : set.ranges) {
    // One range per receiver, and never more ranges than the site has
    // receivers: a hostile part cannot grow a merge.
    if (!open->receivers.insert(r.receiver_id).second ||
        merged.ranges.size() >= static_cast<size_t>(options_.site_receivers)) {
      ++counters_["duplicate_receiver"];
    } else {
      merged.ranges.push_back(r);
    }
  }
}

void RangeSetMerger::Add(const range_set_t& set, int64_t recv_utime, std::vector<Ready>* ready) {
  if (set.num_expected >= options_.site_receivers) {
    ready->push_back({set, recv_utime});
    return;
  }
  ++counters_["parts"];
  const std::pair<int32_t, int32_t> key{set.beacon_id,
                                        static_cast<int32_t>(set.firing_seq & 0xFFFF)};
  const int64_t same_us = static_cast<int64_t>(options_.same_firing_s * 1e6);
  // Saturating: utime is a publisher's word, INT64_MIN included.
  auto apart = [&](int64_t a, int64_t b) {
    const int64_t d = SaturatingDifferenceUs(a, b);
    return d == INT64_MIN ? INT64_MAX : std::llabs(d);
  };
  // The open merge of this firing: same key and a firing time within
  // same_firing_s. A part of the same number far in time (a restarted
  // beacon, the number an hour on, a forged or far-dated part) is another
  // firing and leaves this one alone: releasing it early would give its
  // real parts a pose each (issue #28: a +30 min part between the two real
  // parts of each firing gave three poses per firing).
  auto it = open_.end();
  for (auto [first, last] = open_.equal_range(key); first != last; ++first) {
    if (apart(first->second.set.utime, set.utime) <= same_us) {
      it = first;
      break;
    }
  }
  if (it == open_.end()) {
    // A part of a firing already solved (its sibling came after the
    // deadline): a second pose for one firing would repeat its number with
    // fewer ranges. Counted and dropped; a rising count says the deadline is
    // short for the bridges' hosts.
    for (const auto& [k, utime] : released_) {
      if (k == key && apart(utime, set.utime) <= same_us) {
        ++counters_["late_part"];
        return;
      }
    }
  }
  std::vector<int32_t> signature = PartSignature(set);
  // A part's own count, never negative: a merge completes only when the
  // counts of distinct parts reach the site's receivers.
  const int32_t expected = std::max<int32_t>(set.num_expected, 0);
  if (it == open_.end()) {
    // Bounded: a flood of parts that never complete (a bridge with a wrong
    // --radio, invented firing numbers) releases the oldest.
    constexpr size_t kMaxOpen = 1024;
    if (open_.size() >= kMaxOpen) {
      auto oldest = std::min_element(open_.begin(), open_.end(), [](const auto& a, const auto& b) {
        return a.second.first_recv_utime < b.second.first_recv_utime;
      });
      Release(oldest, recv_utime, "deadline", ready);
    }
    Open open;
    open.set = set;
    open.set.ranges.clear();
    open.set.num_expected = expected;
    open.first_recv_utime = recv_utime;
    Merge(set, &open);
    open.parts.insert(std::move(signature));
    it = open_.emplace(key, std::move(open));
  } else {
    Open& open = it->second;
    if (!open.parts.insert(std::move(signature)).second) {
      ++counters_["duplicate_part"];
      return;
    }
    Merge(set, &open);
    open.set.num_expected = static_cast<int32_t>(
        std::min<int64_t>(int64_t{open.set.num_expected} + expected, options_.site_receivers));
    // The firing time is the earliest arrival of its announcement.
    open.set.utime = std::min(open.set.utime, set.utime);
  }
  if (it->second.set.num_expected >= options_.site_receivers) {
    Release(it, recv_utime, "complete", ready);
  }
}

void RangeSetMerger::Expire(int64_t now_utime, std::vector<Ready>* ready) {
  const int64_t deadline_us = static_cast<int64_t>(options_.deadline_s * 1e6);
  for (auto it = open_.begin(); it != open_.end();) {
    auto next = std::next(it);
    if (now_utime - it->second.first_recv_utime >= deadline_us) {
      Release(it, it->second.first_recv_utime + deadline_us, "deadline", ready);
    }
    it = next;
  }
}

void RangeSetMerger::Flush(int64_t now_utime, std::vector<Ready>* ready) {
  while (!open_.empty()) Release(open_.begin(), now_utime, "deadline", ready);
}

}  // namespace roomfix
