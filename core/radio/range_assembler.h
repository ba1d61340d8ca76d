#ifndef ROOMFIX_CORE_RADIO_RANGE_ASSEMBLER_H_
#define ROOMFIX_CORE_RADIO_RANGE_ASSEMBLER_H_

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/radio/wall_payload.h"
#include "core/world/site.h"

namespace roomfix::radio {

// A receiver's range: the time of flight times the speed of sound, minus
// the receiver's calibrated offset (Receiver::range_offset_m). The one
// formula for live assembly and for `roomfix replay --site`, which re-derives
// recorded ranges with new offsets.
inline double RangeFromTimeOfFlight(double time_of_flight_us, double speed_of_sound_mps,
                                    double range_offset_m) {
  return time_of_flight_us * 1e-6 * speed_of_sound_mps - range_offset_m;
}

struct AssemblerOptions {
  // A firing's set is published this long after its first packet arrived
  // (normally the beacon's announcement) if some receiver has not answered
  // by then. Reports that come later are dropped as late_report.
  double deadline_s = 0.05;
  // Air temperature when no receiver (or the beacon) reports a plausible
  // one, degC.
  double default_temperature_c = 20.0;
  // Temperature readings outside this band are ignored (a failed sensor).
  double min_plausible_temperature_c = -20.0;
  double max_plausible_temperature_c = 60.0;
  // A range must lie within what the room allows: between the smallest and
  // largest distance from the receiver to a point of the floor rectangle
  // raised to the beacon's height, widened by this margin plus the
  // receiver's |range offset|.
  double range_margin_m = 0.3;
  // Firings more than this many behind the newest of their beacon are
  // stale: their reports are dropped (stale_firing).
  int stale_window_firings = 64;
  // A beacon restarted its counter when it announces a firing more than
  // max_open_firings behind its newest announcement, or behind it at all
  // after nothing about it was heard for this long (a power cycle takes
  // longer; a late copy from a buffering radio comes while the beacon is
  // still talking). A restart within this time after fewer than
  // max_open_firings firings goes unnoticed until the new count passes the
  // old one: those firings are dropped as late_report.
  double restart_silence_s = 0.5;
  // At most this many firings of one beacon are assembled at once; opening
  // one more closes the oldest early (counted as sets_evicted).
  int max_open_firings = 16;

  bool IsValid(std::string* error) const;
};

// One radio packet as the coordinator delivered it.
struct RadioPacket {
  // Source addresses from the receive frame (0x90 has both, 0x80 only the
  // 64-bit one, 0x81 only the 16-bit one).
  bool has_address64 = false;
  uint64_t address64 = 0;
  bool has_address16 = false;
  uint16_t address16 = 0;
  const uint8_t* payload = nullptr;
  size_t payload_size = 0;
  // Host clock when the last byte of the frame was read, microseconds since
  // the Unix epoch.
  int64_t arrival_utime = 0;
};

struct AssembledRange {
  int receiver_id = 0;
  std::array<double, 3> receiver_position_m{};
  double time_of_flight_us = 0.0;
  // time of flight x speed of sound - the receiver's range offset.
  double range_m = 0.0;
  int64_t arrival_utime = 0;
};

enum class CloseReason {
  // Every expected receiver answered.
  kComplete,
  // The deadline passed first.
  kDeadline,
  // Too many firings of the beacon were open at once.
  kEvicted,
  // Flush() at shutdown or a beacon restart.
  kFlushed,
};

const char* CloseReasonName(CloseReason reason);

// One firing of one beacon, ready to publish as a range_set_t.
struct AssembledSet {
  // The firing time: the announcement's arrival; without an announcement,
  // the earliest report's arrival minus its time of flight (an estimate that
  // radio buffering makes late; counted as missing_announcement).
  int64_t fire_utime = 0;
  bool fire_time_from_announcement = false;
  int beacon_id = 0;
  // Unwrapped to 64 bits: only grows within a session, across 16-bit
  // wrap-around and beacon restarts (after a restart the beacon's 0 follows
  // the newest number before it).
  int64_t firing_seq = 0;
  double speed_of_sound_mps = 0.0;
  double temperature_c = 0.0;
  // Receivers expected to answer (every receiver of the site).
  int num_expected = 0;
  // Receivers that answered, including those whose report held no usable
  // range (no echo, range outside the room).
  int num_answered = 0;
  std::vector<AssembledRange> ranges;
  CloseReason close_reason = CloseReason::kComplete;
  int64_t close_utime = 0;
};

// Groups the wall devices' radio reports into one set per beacon firing.
//
// Reports are keyed by (beacon id, unwrapped firing sequence number), never
// by arrival time, so bursts, delays and reordering by the radio cannot mix
// two firings. A report is refused, counted by reason, when:
//   unknown_address      its source is not a receiver or beacon of the site
//   wrong_sender         a report from a beacon, an announcement from a
//                        receiver, or an announcement for another beacon id
//   malformed_payload    bad length, type, CRC or beacon id 0
//   unsupported_version  a payload version this bridge does not read
//   unknown_beacon       it names a beacon the site does not list
//   late_report          its firing was already published
//   stale_firing         its firing is far older than the beacon's newest
//   future_firing        its firing is far ahead of the beacon's newest
//                        announcement while the beacon is announcing, or
//                        far ahead of the newest firing and no other
//                        receiver has named it yet
//   duplicate_report     the receiver already answered this firing
//   no_echo              the receiver heard nothing (answers, no range)
//   tof_out_of_range     the range is impossible in this room
// A set closes when every site receiver has answered, when its deadline
// passes (Advance), or when too many firings of its beacon are open.
//
// Pure: time comes in with each packet and each Advance call; no clock.
class RangeAssembler {
 public:
  RangeAssembler(const Site& site, const AssemblerOptions& options);

  // Takes one packet; appends any set it completes to *closed. Returns the
  // rejection reason, or nullptr when the packet was used.
  const char* OnPacket(const RadioPacket& packet, std::vector<AssembledSet>* closed);
  // Closes every set whose deadline is at or before now_utime.
  void Advance(int64_t now_utime, std::vector<AssembledSet>* closed);
  // Closes every open set (shutdown).
  void Flush(int64_t now_utime, std::vector<AssembledSet>* closed);
  // The earliest deadline of an open set, or INT64_MAX when none is open.
  int64_t NextDeadlineUtime() const;

  // Counters: rejections by reason (see above) and events
  // (announcements, reports, sets_published, sets_complete, sets_deadline,
  // sets_evicted, sets_flushed, missing_announcement, beacon_restarts,
  // implausible_temperature).
  const std::map<std::string, int64_t>& rejected() const { return rejected_; }
  const std::map<std::string, int64_t>& counters() const { return counters_; }
  int64_t rejected(const std::string& reason) const;
  int64_t counter(const std::string& name) const;
  // The last rejection, one line with the source address and reason.
  const std::string& last_rejection() const { return last_rejection_; }
  int open_firings() const;

 private:
  struct Answer {
    int receiver_index = 0;
    bool has_range = false;
    AssembledRange range;
    double raw_range_m = 0.0;  // tof x speed of sound used at acceptance
    uint32_t time_of_flight_ns = 0;
    int64_t arrival_utime = 0;
  };
  struct OpenFiring {
    int64_t seq = 0;
    int64_t opened_utime = 0;
    int64_t deadline_utime = 0;
    bool has_announcement = false;
    int64_t announcement_utime = 0;
    std::vector<double> temperatures_c;
    std::vector<Answer> answers;
  };
  struct BeaconState {
    const Beacon* beacon = nullptr;
    bool has_newest = false;
    // Newest firing number, unwrapped, in the beacon's own counting; the
    // published number adds seq_offset, which grows at each beacon restart
    // so that published numbers keep increasing.
    int64_t newest_seq = 0;
    int64_t seq_offset = 0;
    // The newest firing the beacon itself announced: restarts and the window
    // for reports are judged against it, not against reports, which a
    // buffering radio can deliver from an old numbering.
    bool has_announced = false;
    int64_t newest_announced = 0;
    int64_t last_announcement_utime = INT64_MIN;
    // Any packet about this beacon (announcement or report).
    int64_t last_packet_utime = INT64_MIN;
    // A report that would move the count far ahead, waiting for a second
    // receiver to name the same firing.
    int64_t jump_seq = INT64_MIN;
    int jump_receiver = -1;
    int64_t jump_utime = 0;
    // After a restart, firings before its first are of the old numbering
    // and refused as stale: letting them in would reuse published numbers.
    int64_t floor_seq = INT64_MIN;
    // Slot seq % size holds seq once that firing was closed.
    std::vector<int64_t> closed;
    std::vector<OpenFiring> open;
    // Per receiver (site order): the ranges the room allows between it and
    // this beacon's emitter plane.
    std::vector<double> min_range_m;
    std::vector<double> max_range_m;
  };

  const char* Reject(const char* reason, const std::string& detail);
  BeaconState* FindBeaconState(int beacon_id);
  int64_t Unwrap(const BeaconState& state, uint16_t seq) const;
  bool IsClosed(const BeaconState& state, int64_t seq) const;
  OpenFiring* FindOpen(BeaconState* state, int64_t seq);
  OpenFiring* OpenNew(BeaconState* state, int64_t seq, int64_t now_utime,
                      std::vector<AssembledSet>* closed);
  void Close(BeaconState* state, size_t index, CloseReason reason, int64_t now_utime,
             std::vector<AssembledSet>* closed);
  void NoteTemperature(const WallMessage& message, OpenFiring* firing);
  const char* OnAnnouncement(BeaconState* state, const WallMessage& message,
                             const RadioPacket& packet, std::vector<AssembledSet>* closed);
  const char* OnReport(int receiver_index, const WallMessage& message, const RadioPacket& packet,
                       std::vector<AssembledSet>* closed);

  const Site& site_;
  AssemblerOptions options_;
  std::vector<BeaconState> beacons_;
  std::map<std::string, int64_t> rejected_;
  std::map<std::string, int64_t> counters_;
  std::string last_rejection_;
  std::string detail_;
};

// Maps a 16-bit firing number to the 64-bit value nearest to `newest`
// (serial-number arithmetic, RFC 1982): correct as long as reports are less
// than 32768 firings (55 minutes at 10 Hz) away from the newest one.
int64_t UnwrapSequence(uint16_t seq, int64_t newest);

}  // namespace roomfix::radio

#endif  // ROOMFIX_CORE_RADIO_RANGE_ASSEMBLER_H_
