#include "tests/testing/ledger_check.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "roomfix/range_set_t.hpp"
#include "tests/testing/demo_site.h"

namespace roomfix {
namespace {

void Fail(LedgerCheck* check, const std::string& text) {
  if (check->failures.size() < 10) check->failures.push_back(text);
}

}  // namespace

Site LoadDemoSite() {
  Site site;
  std::string error;
  EXPECT_TRUE(LoadSite(testing::DemoSitePath(), &site, &error)) << error;
  return site;
}

LedgerCheck CheckAgainstLedger(const std::vector<range_set_t>& sets,
                               const VirtualWallDevices& devices,
                               const LedgerCheckOptions& options) {
  LedgerCheck check;
  const auto& ledger = devices.ledger();
  std::map<std::pair<int, int64_t>, const range_set_t*> published;
  for (const range_set_t& set : sets) {
    ++check.sets;
    const std::pair<int, int64_t> key{set.beacon_id, set.firing_seq};
    if (!published.emplace(key, &set).second) {
      ++check.repeated_sets;
      Fail(&check, "firing " + std::to_string(set.firing_seq) + " published twice");
    }
    const auto it = ledger.find({set.beacon_id, set.firing_seq - options.first_seq});
    if (it == ledger.end()) {
      ++check.mixed_sets;
      Fail(&check, "set for firing " + std::to_string(set.firing_seq) + " never fired");
      continue;
    }
    bool mixed = false;
    for (const range_t& r : set.ranges) {
      ++check.ranges;
      const auto report = std::find_if(
          it->second.reports.begin(), it->second.reports.end(),
          [&](const FiringRecord::Report& rep) { return rep.receiver_id == r.receiver_id; });
      // The wire carries whole nanoseconds; the message microseconds.
      const bool same = report != it->second.reports.end() && !report->no_echo &&
                        report->delivery_utime >= 0 &&
                        std::abs(report->time_of_flight_ns - r.time_of_flight_us * 1e3) < 0.5;
      if (!same) {
        mixed = true;
        Fail(&check, "firing " + std::to_string(set.firing_seq) + " receiver " +
                         std::to_string(r.receiver_id) + " holds a time of flight of " +
                         std::to_string(r.time_of_flight_us) + " us that it did not send");
      }
    }
    if (mixed) ++check.mixed_sets;
  }

  std::vector<int64_t> disturbances = devices.disturbance_utimes();
  std::sort(disturbances.begin(), disturbances.end());
  const auto deadline_us = static_cast<int64_t>(std::llround(options.deadline_s * 1e6));
  const auto margin_us = static_cast<int64_t>(std::llround(options.margin_s * 1e6));
  const auto window_us = static_cast<int64_t>(std::llround(options.disturbance_window_s * 1e6));
  std::map<int, bool> awaiting_restart;  // per beacon
  for (const auto& [key, record] : ledger) {
    bool& awaiting = awaiting_restart[key.first];
    if (record.after_restart) awaiting = true;
    if (awaiting) {
      int64_t earliest_report = INT64_MAX;
      for (const FiringRecord::Report& rep : record.reports) {
        if (rep.delivery_utime >= 0)
          earliest_report = std::min(earliest_report, rep.delivery_utime);
      }
      if (record.announcement_utime < 0 || !record.announcement_intact ||
          record.announcement_utime > earliest_report) {
        continue;
      }
      awaiting = false;
    }
    int64_t first = INT64_MAX;
    int64_t last = INT64_MIN;
    bool all_intact = true;
    if (record.announcement_utime >= 0 && record.announcement_intact) {
      first = record.announcement_utime;
    }
    for (const FiringRecord::Report& rep : record.reports) {
      if (rep.delivery_utime < 0 || !rep.intact) {
        all_intact = false;
        break;
      }
      first = std::min(first, rep.delivery_utime);
      last = std::max(last, rep.delivery_utime);
    }
    if (!all_intact || last > first + deadline_us - margin_us) continue;
    if (last + deadline_us > options.judge_until_utime) continue;
    bool written_late = false;
    for (const auto& [scheduled, written] : options.late_writes) {
      written_late |= scheduled <= last && written >= first;
    }
    if (written_late) continue;
    if (options.skip_disturbed) {
      const auto lo = std::lower_bound(disturbances.begin(), disturbances.end(), first - window_us);
      if (lo != disturbances.end() && *lo <= last) continue;
    }
    ++check.expected_complete;
    const auto it = published.find({key.first, key.second + options.first_seq});
    size_t with_echo = 0;
    // A receiver armed inside another pulse's tail reads a time of flight
    // near 0, which the bridge drops as a range the room cannot hold.
    for (const FiringRecord::Report& rep : record.reports) {
      with_echo += rep.no_echo || rep.air == Detection::Kind::kArmedInTail ? 0 : 1;
    }
    if (it == published.end() || it->second->ranges.size() != with_echo) {
      ++check.incomplete;
      Fail(&check, "firing " + std::to_string(key.second) + " arrived complete but was " +
                       (it == published.end()
                            ? std::string("not published")
                            : "published with " + std::to_string(it->second->ranges.size()) +
                                  " of " + std::to_string(with_echo) + " ranges"));
    }
  }
  return check;
}

}  // namespace roomfix
