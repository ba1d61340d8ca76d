#ifndef ROOMFIX_TRILAT_PROC_RANGE_SET_MERGER_H_
#define ROOMFIX_TRILAT_PROC_RANGE_SET_MERGER_H_

#include <cstdint>
#include <deque>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "roomfix/range_set_t.hpp"

namespace roomfix {

// Joins the parts of one firing's range set that several coordinators'
// bridges publish (docs/trilateration.md, "Several radios").
//
// A bridge run with --radio publishes sets that expect only its radio's
// receivers: num_expected below the site's receiver count marks a part. A
// part waits until the parts of the same firing together expect every
// receiver of the site (merged: complete), or until deadline_s after the
// first part arrived (merged with what came: deadline). A whole set
// (num_expected at or above the site's count) passes at once, untouched:
// one bridge for the whole site behaves as before.
//
// The same firing: same beacon, same firing number modulo 2^16 (what the
// radio carries; each bridge unwraps it on its own, and a bridge started
// later unwraps from a different base), and firing times within
// same_firing_s of each other (the announcement's arrival on two hosts:
// radio latency and the hosts' clock offset, a few ms under NTP; one beacon
// fires at most every slot, 2^16 firings apart is an hour). A part with the
// same beacon and number but a firing time farther than same_firing_s from
// an open merge is another firing (a restarted beacon, or a forged or
// far-dated part): it opens a merge of its own and never releases, joins or
// splits the open one, so a firing gets at most one pose whatever parts
// arrive between its own.
struct RangeSetMergerOptions {
  double deadline_s = 0.05;
  double same_firing_s = 0.5;
  // The site's receivers: what a merged set expects in all.
  int site_receivers = 0;
  // Which radio carries each receiver (the site's `radios`; empty when it
  // names none). A part is attributed to its ranges' radio, so a repeated
  // part (a replayed datagram, two bridges started with the same --radio)
  // cannot stand in for the other radio's part and complete the firing.
  std::map<int32_t, int32_t> radio_of_receiver;

  bool IsValid(std::string* error) const;
};

class RangeSetMerger {
 public:
  explicit RangeSetMerger(const RangeSetMergerOptions& options);

  struct Ready {
    range_set_t set;
    // The receive time of the part that completed it, or the deadline.
    int64_t recv_utime = 0;
  };
  // Takes a set received at recv_utime; appends what is ready to solve.
  void Add(const range_set_t& set, int64_t recv_utime, std::vector<Ready>* ready);
  // Releases merges whose deadline has passed by now_utime.
  void Expire(int64_t now_utime, std::vector<Ready>* ready);
  // Releases everything (shutdown).
  void Flush(int64_t now_utime, std::vector<Ready>* ready);
  size_t open() const { return open_.size(); }

  // parts (sets that were parts), complete, deadline (released with what
  // came), duplicate_receiver (a receiver in two parts: the first kept),
  // late_part (a part of a firing already released: dropped), duplicate_part
  // (a second part from the same radio, or the same receivers, for one
  // firing: dropped).
  const std::map<std::string, int64_t>& counters() const { return counters_; }

 private:
  struct Open {
    range_set_t set;
    int64_t first_recv_utime = 0;
    // Receivers merged so far, and the parts taken: by radio when the site
    // names radios, otherwise by the part's receiver list.
    std::set<int32_t> receivers;
    std::set<std::vector<int32_t>> parts;
  };
  // What identifies where a part came from (see Open::parts).
  std::vector<int32_t> PartSignature(const range_set_t& set) const;
  void Merge(const range_set_t& set, Open* open);
  using OpenMap = std::multimap<std::pair<int32_t, int32_t>, Open>;
  void Release(OpenMap::iterator it, int64_t recv_utime, const char* why,
               std::vector<Ready>* ready);

  RangeSetMergerOptions options_;
  // By (beacon, firing number mod 2^16); several merges share a key only
  // when their firing times are more than same_firing_s apart.
  OpenMap open_;
  // The firings released last (key, firing time), to recognise late parts.
  static constexpr size_t kMaxReleased = 256;
  std::deque<std::pair<std::pair<int32_t, int32_t>, int64_t>> released_;
  std::map<std::string, int64_t> counters_;
};

}  // namespace roomfix

#endif  // ROOMFIX_TRILAT_PROC_RANGE_SET_MERGER_H_
