#ifndef ROOMFIX_TESTS_TESTING_LEDGER_CHECK_H_
#define ROOMFIX_TESTS_TESTING_LEDGER_CHECK_H_

#include <cstdint>
#include <string>
#include <vector>

#include "msgio/lcm_types_fwd.h"
#include "sim/wall_devices.h"

namespace roomfix {

// The verdict on a bridge's range sets against what the virtual wall
// devices really sent (their ledger).
struct LedgerCheck {
  int sets = 0;
  int ranges = 0;
  // Sets holding a range that is not its receiver's report for that firing
  // (another firing's, a foreign module's, a corrupted one): must be 0.
  int mixed_sets = 0;
  // Firings published more than once: must be 0.
  int repeated_sets = 0;
  // Firings whose every report arrived intact before the deadline, and how
  // many of them were not published complete: must be 0. After a beacon
  // restart, firings are judged again from the first whose announcement
  // arrived intact before its reports (the bridge cannot know the new count
  // before).
  int expected_complete = 0;
  int incomplete = 0;
  std::vector<std::string> failures;  // the first few, for the test output
};

struct LedgerCheckOptions {
  double deadline_s = 0.05;
  // Reports must arrive this much before the deadline to count as on time
  // (absorbs scheduling jitter between the pseudo-terminal's writer and the
  // bridge in real-time tests).
  double margin_s = 0.001;
  // Firings after this are not judged for completeness (still in flight).
  int64_t judge_until_utime = INT64_MAX;
  // API mode 1: firings near a corrupted frame or garbage are not judged
  // for completeness (see VirtualWallDevices::disturbance_utimes).
  bool skip_disturbed = false;
  // The bridge numbers firings from the first 16-bit number it hears:
  // published = ledger seq + first_seq (WallDevicesOptions::first_seq).
  int64_t first_seq = 0;
  // Writes that reached the pseudo-terminal late, as [scheduled, written]
  // intervals (a stalled writer thread): firings with a delivery inside one
  // are not judged for completeness, since the ledger's times are wrong
  // for them.
  std::vector<std::pair<int64_t, int64_t>> late_writes;
  // The bridge accepts at most 128 bytes of frame data, so a bogus length
  // holds back at most that many bytes: a few frames, under 0.15 s.
  double disturbance_window_s = 0.15;
};

// config/sites/demo_room.yaml, the site the radio tests run on; a load
// failure is a test failure.
Site LoadDemoSite();

LedgerCheck CheckAgainstLedger(const std::vector<range_set_t>& sets,
                               const VirtualWallDevices& devices,
                               const LedgerCheckOptions& options);

}  // namespace roomfix

#endif  // ROOMFIX_TESTS_TESTING_LEDGER_CHECK_H_
