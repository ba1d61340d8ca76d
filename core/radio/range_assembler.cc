#include "core/radio/range_assembler.h"

#include <fmt/format.h>

#include <algorithm>
#include <climits>
#include <cmath>

#include "core/world/ultrasound_model.h"

namespace roomfix::radio {
namespace {

// Closed-firing memory per beacon; must exceed the stale window so that a
// late report is told apart from a stale one.
constexpr int64_t kClosedSlots = 1024;
constexpr uint64_t kUnknownAddress64 = 0xFFFFFFFFFFFFFFFFull;

int64_t Slot(int64_t seq) { return ((seq % kClosedSlots) + kClosedSlots) % kClosedSlots; }

double Median(std::vector<double> values) {
  const size_t mid = values.size() / 2;
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid), values.end());
  if (values.size() % 2 == 1) return values[mid];
  const double upper = values[mid];
  const double lower =
      *std::max_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(mid));
  return 0.5 * (lower + upper);
}

// Smallest and largest distance from point p to the axis-aligned rectangle
// [x0, x1] x [y0, y1] at height z.
void RectangleDistances(const std::array<double, 3>& p, double x0, double x1, double y0, double y1,
                        double z, double* min_m, double* max_m) {
  const double dz = p[2] - z;
  const double nx = std::clamp(p[0], x0, x1) - p[0];
  const double ny = std::clamp(p[1], y0, y1) - p[1];
  *min_m = std::sqrt(nx * nx + ny * ny + dz * dz);
  const double fx = std::max(std::abs(p[0] - x0), std::abs(p[0] - x1));
  const double fy = std::max(std::abs(p[1] - y0), std::abs(p[1] - y1));
  *max_m = std::sqrt(fx * fx + fy * fy + dz * dz);
}

}  // namespace

bool AssemblerOptions::IsValid(std::string* error) const {
  if (!(deadline_s > 0.0 && deadline_s <= 10.0)) {
    *error = "deadline must be in (0, 10] s";
    return false;
  }
  if (!std::isfinite(default_temperature_c) || default_temperature_c < -40.0 ||
      default_temperature_c > 80.0) {
    *error = "default temperature must be in [-40, 80] degC";
    return false;
  }
  if (!(min_plausible_temperature_c < max_plausible_temperature_c)) {
    *error = "plausible temperature band is empty";
    return false;
  }
  if (!(range_margin_m >= 0.0 && range_margin_m < 100.0)) {
    *error = "range margin must be in [0, 100) m";
    return false;
  }
  if (stale_window_firings < 1 || stale_window_firings > kClosedSlots / 2) {
    *error = "stale window must be 1 to " + std::to_string(kClosedSlots / 2) + " firings";
    return false;
  }
  if (!(restart_silence_s > 0.0)) {
    *error = "restart silence must be positive";
    return false;
  }
  if (max_open_firings < 1 || max_open_firings > stale_window_firings) {
    *error = "max open firings must be 1 to the stale window";
    return false;
  }
  return true;
}

const char* CloseReasonName(CloseReason reason) {
  switch (reason) {
    case CloseReason::kComplete:
      return "complete";
    case CloseReason::kDeadline:
      return "deadline";
    case CloseReason::kEvicted:
      return "evicted";
    case CloseReason::kFlushed:
      return "flushed";
  }
  return "unknown";
}

int64_t UnwrapSequence(uint16_t seq, int64_t newest) {
  const auto delta =
      static_cast<int16_t>(static_cast<uint16_t>(seq - static_cast<uint16_t>(newest)));
  return newest + delta;
}

RangeAssembler::RangeAssembler(const Site& site, const AssemblerOptions& options)
    : site_(site), options_(options) {
  const double x0 = site.room.min_x_m;
  const double x1 = x0 + site.room.size_x_m;
  const double y0 = site.room.min_y_m;
  const double y1 = y0 + site.room.size_y_m;
  for (const Beacon& beacon : site.beacons) {
    BeaconState state;
    state.beacon = &beacon;
    state.closed.assign(kClosedSlots, INT64_MIN);
    for (const Receiver& r : site.receivers) {
      double lo = 0.0;
      double hi = 0.0;
      RectangleDistances(r.position_m, x0, x1, y0, y1, beacon.height_m, &lo, &hi);
      const double margin = options.range_margin_m + std::abs(r.range_offset_m);
      state.min_range_m.push_back(std::max(0.0, lo - margin));
      state.max_range_m.push_back(hi + margin);
    }
    beacons_.push_back(std::move(state));
  }
}

int64_t RangeAssembler::rejected(const std::string& reason) const {
  const auto it = rejected_.find(reason);
  return it == rejected_.end() ? 0 : it->second;
}

int64_t RangeAssembler::counter(const std::string& name) const {
  const auto it = counters_.find(name);
  return it == counters_.end() ? 0 : it->second;
}

int RangeAssembler::open_firings() const {
  int n = 0;
  for (const BeaconState& b : beacons_) n += static_cast<int>(b.open.size());
  return n;
}

const char* RangeAssembler::Reject(const char* reason, const std::string& detail) {
  ++rejected_[reason];
  last_rejection_ = std::string(reason) + ": " + detail;
  return reason;
}

RangeAssembler::BeaconState* RangeAssembler::FindBeaconState(int beacon_id) {
  for (BeaconState& b : beacons_) {
    if (b.beacon->id == beacon_id) return &b;
  }
  return nullptr;
}

int64_t RangeAssembler::Unwrap(const BeaconState& state, uint16_t seq) const {
  return state.has_newest ? UnwrapSequence(seq, state.newest_seq) : seq;
}

bool RangeAssembler::IsClosed(const BeaconState& state, int64_t seq) const {
  return state.closed[static_cast<size_t>(Slot(seq))] == seq;
}

RangeAssembler::OpenFiring* RangeAssembler::FindOpen(BeaconState* state, int64_t seq) {
  for (OpenFiring& f : state->open) {
    if (f.seq == seq) return &f;
  }
  return nullptr;
}

RangeAssembler::OpenFiring* RangeAssembler::OpenNew(BeaconState* state, int64_t seq,
                                                    int64_t now_utime,
                                                    std::vector<AssembledSet>* closed) {
  if (static_cast<int>(state->open.size()) >= options_.max_open_firings) {
    size_t oldest = 0;
    for (size_t i = 1; i < state->open.size(); ++i) {
      if (state->open[i].seq < state->open[oldest].seq) oldest = i;
    }
    Close(state, oldest, CloseReason::kEvicted, now_utime, closed);
  }
  OpenFiring f;
  f.seq = seq;
  f.opened_utime = now_utime;
  f.deadline_utime = now_utime + static_cast<int64_t>(std::llround(options_.deadline_s * 1e6));
  state->open.push_back(std::move(f));
  return &state->open.back();
}

void RangeAssembler::NoteTemperature(const WallMessage& message, OpenFiring* firing) {
  if (!message.has_temperature()) return;
  const double t = message.temperature_c();
  if (t < options_.min_plausible_temperature_c || t > options_.max_plausible_temperature_c) {
    ++counters_["implausible_temperature"];
    return;
  }
  firing->temperatures_c.push_back(t);
}

const char* RangeAssembler::OnPacket(const RadioPacket& packet, std::vector<AssembledSet>* closed) {
  const Receiver* receiver = nullptr;
  const Beacon* beacon = nullptr;
  std::string source;
  if (packet.has_address64 && packet.address64 != kUnknownAddress64) {
    receiver = site_.FindReceiverByAddress(packet.address64);
    beacon = site_.FindBeaconByAddress(packet.address64);
    source = FormatRadioAddress(packet.address64);
  } else if (packet.has_address16 && !packet.has_address64) {
    // 802.15.4 short addressing (frame 0x81): only modules given a
    // short_address in the site file can be recognised.
    receiver = site_.FindReceiverByShortAddress(packet.address16);
    beacon = site_.FindBeaconByShortAddress(packet.address16);
    source = fmt::format("short address 0x{:04X}", packet.address16);
  } else {
    source = "unknown 64-bit address";
  }
  if (receiver == nullptr && beacon == nullptr) {
    return Reject("unknown_address", source + " is not in the site file");
  }

  WallMessage message;
  std::string detail;
  const PayloadError error =
      DecodeWallMessage(packet.payload, packet.payload_size, &message, &detail);
  if (error == PayloadError::kUnsupportedVersion) {
    return Reject("unsupported_version", source + ": " + detail);
  }
  if (error != PayloadError::kOk) {
    return Reject("malformed_payload", source + ": " + detail);
  }

  if (message.type == PayloadType::kFiring) {
    if (beacon == nullptr) {
      return Reject("wrong_sender", source + " (receiver " + std::to_string(receiver->id) +
                                        ") sent a firing announcement");
    }
    if (message.beacon_id != beacon->id) {
      return Reject("wrong_sender", source + " is beacon " + std::to_string(beacon->id) +
                                        " but announced beacon " +
                                        std::to_string(message.beacon_id));
    }
    return OnAnnouncement(FindBeaconState(beacon->id), message, packet, closed);
  }
  if (receiver == nullptr) {
    return Reject("wrong_sender",
                  source + " (beacon " + std::to_string(beacon->id) + ") sent a range report");
  }
  return OnReport(static_cast<int>(receiver - site_.receivers.data()), message, packet, closed);
}

const char* RangeAssembler::OnAnnouncement(BeaconState* state, const WallMessage& message,
                                           const RadioPacket& packet,
                                           std::vector<AssembledSet>* closed) {
  ++counters_["announcements"];
  int64_t seq = Unwrap(*state, message.firing_seq);
  const bool after_silence = state->last_packet_utime != INT64_MIN &&
                             packet.arrival_utime - state->last_packet_utime >
                                 static_cast<int64_t>(options_.restart_silence_s * 1e6);
  state->last_packet_utime = std::max(state->last_packet_utime, packet.arrival_utime);
  // Only the beacon itself can send an announcement (its address, a valid
  // CRC), so one far behind its newest announcement, or behind it at all
  // after a silence, means its counter started again (a power cycle). A copy
  // delayed by a buffering radio is a few firings late and comes while the
  // beacon is still talking.
  if (state->has_announced && (seq < state->newest_announced - options_.max_open_firings ||
                               (after_silence && seq < state->newest_announced))) {
    // Publish what is open and continue the numbering after the newest, so
    // that published numbers still only grow. A beacon counts from 0 after
    // a restart, so the new count's 0 follows the old newest even when its
    // first firings were not heard.
    while (!state->open.empty()) {
      Close(state, 0, CloseReason::kFlushed, packet.arrival_utime, closed);
    }
    state->seq_offset += state->newest_seq + 1;
    state->newest_seq = message.firing_seq;
    state->newest_announced = message.firing_seq;
    std::fill(state->closed.begin(), state->closed.end(), INT64_MIN);
    seq = message.firing_seq;
    state->floor_seq = seq;
    ++counters_["beacon_restarts"];
  }
  if (seq < state->floor_seq ||
      (state->has_newest && seq < state->newest_seq - options_.stale_window_firings)) {
    return Reject("stale_firing", "announcement of beacon " + std::to_string(state->beacon->id) +
                                      " firing " + std::to_string(seq + state->seq_offset) +
                                      ", before its restart or far behind its newest");
  }
  if (IsClosed(*state, seq)) {
    return Reject("late_report", "announcement of beacon " + std::to_string(state->beacon->id) +
                                     " firing " + std::to_string(seq + state->seq_offset) +
                                     " after its set was published");
  }
  OpenFiring* firing = FindOpen(state, seq);
  if (firing == nullptr) firing = OpenNew(state, seq, packet.arrival_utime, closed);
  if (firing->has_announcement) {
    return Reject("duplicate_report", "second announcement of beacon " +
                                          std::to_string(state->beacon->id) + " firing " +
                                          std::to_string(seq + state->seq_offset));
  }
  firing->has_announcement = true;
  firing->announcement_utime = packet.arrival_utime;
  NoteTemperature(message, firing);
  if (!state->has_newest || seq > state->newest_seq) state->newest_seq = seq;
  state->has_newest = true;
  if (!state->has_announced || seq > state->newest_announced) state->newest_announced = seq;
  state->has_announced = true;
  state->last_announcement_utime = std::max(state->last_announcement_utime, packet.arrival_utime);
  return nullptr;
}

const char* RangeAssembler::OnReport(int receiver_index, const WallMessage& message,
                                     const RadioPacket& packet, std::vector<AssembledSet>* closed) {
  ++counters_["reports"];
  const Receiver& receiver = site_.receivers[static_cast<size_t>(receiver_index)];
  BeaconState* state = FindBeaconState(message.beacon_id);
  if (state == nullptr) {
    return Reject("unknown_beacon", "receiver " + std::to_string(receiver.id) +
                                        " answered beacon " + std::to_string(message.beacon_id) +
                                        ", which the site does not list");
  }
  state->last_packet_utime = std::max(state->last_packet_utime, packet.arrival_utime);
  const int64_t seq = Unwrap(*state, message.firing_seq);
  const std::string what = "receiver " + std::to_string(receiver.id) + " report for beacon " +
                           std::to_string(state->beacon->id) + " firing " +
                           std::to_string(seq + state->seq_offset);
  if (IsClosed(*state, seq)) return Reject("late_report", what + " after its set was published");
  if (seq < state->floor_seq ||
      (state->has_newest && seq < state->newest_seq - options_.stale_window_firings)) {
    return Reject("stale_firing", what + ", " + std::to_string(state->newest_seq - seq) +
                                      " firings behind the newest");
  }  // While the beacon is announcing, a report far ahead of its announcements
  // belongs to another numbering: a buffered report from before a restart
  // unwraps ahead of the new count. Letting it in would move the newest
  // firing and make the real ones look stale.
  if (state->has_announced &&
      packet.arrival_utime - state->last_announcement_utime <=
          static_cast<int64_t>(options_.restart_silence_s * 1e6) &&
      seq > state->newest_announced + options_.max_open_firings) {
    return Reject("future_firing", what + ", " + std::to_string(seq - state->newest_announced) +
                                       " firings ahead of the beacon's announcements");
  }
  // Without recent announcements, reports must carry the count forward
  // (the coordinator may not hear the beacon for a while), but one report
  // alone may not move it far: a second receiver must name the same firing.
  // Otherwise a single stray report would make every real firing stale.
  if (state->has_newest && seq > state->newest_seq + options_.max_open_firings &&
      FindOpen(state, seq) == nullptr) {
    const bool corroborated =
        state->jump_seq == seq && state->jump_receiver != receiver_index &&
        packet.arrival_utime - state->jump_utime <= static_cast<int64_t>(options_.deadline_s * 1e6);
    if (!corroborated) {
      state->jump_seq = seq;
      state->jump_receiver = receiver_index;
      state->jump_utime = packet.arrival_utime;
      return Reject("future_firing", what + ", " + std::to_string(seq - state->newest_seq) +
                                         " firings ahead of the newest, named by one receiver");
    }
  }

  OpenFiring* firing = FindOpen(state, seq);
  if (firing == nullptr) firing = OpenNew(state, seq, packet.arrival_utime, closed);
  for (const Answer& a : firing->answers) {
    if (a.receiver_index == receiver_index) return Reject("duplicate_report", what + " repeated");
  }
  if (!state->has_newest || seq > state->newest_seq) state->newest_seq = seq;
  state->has_newest = true;

  NoteTemperature(message, firing);
  Answer answer;
  answer.receiver_index = receiver_index;
  answer.time_of_flight_ns = message.time_of_flight_ns;
  answer.arrival_utime = packet.arrival_utime;
  const char* reason = nullptr;
  if ((message.flags & kFlagNoEcho) != 0 || message.time_of_flight_ns == 0) {
    reason = Reject("no_echo", what + ": no echo heard");
  } else {
    const double t = message.has_temperature() &&
                             message.temperature_c() >= options_.min_plausible_temperature_c &&
                             message.temperature_c() <= options_.max_plausible_temperature_c
                         ? message.temperature_c()
                         : options_.default_temperature_c;
    const double raw_m = message.time_of_flight_ns * 1e-9 * SpeedOfSound(t);
    const double lo = state->min_range_m[static_cast<size_t>(receiver_index)];
    const double hi = state->max_range_m[static_cast<size_t>(receiver_index)];
    if (raw_m < lo || raw_m > hi) {
      reason =
          Reject("tof_out_of_range",
                 what + fmt::format(": {:.3f} m is outside [{:.3f}, {:.3f}] m", raw_m, lo, hi));
    } else {
      answer.has_range = true;
    }
  }
  firing->answers.push_back(answer);
  if (firing->answers.size() == site_.receivers.size()) {
    const size_t index = static_cast<size_t>(firing - state->open.data());
    Close(state, index, CloseReason::kComplete, packet.arrival_utime, closed);
  }
  return reason;
}

void RangeAssembler::Close(BeaconState* state, size_t index, CloseReason reason, int64_t now_utime,
                           std::vector<AssembledSet>* closed) {
  OpenFiring& f = state->open[index];
  AssembledSet set;
  set.beacon_id = state->beacon->id;
  set.firing_seq = f.seq + state->seq_offset;
  set.temperature_c =
      f.temperatures_c.empty() ? options_.default_temperature_c : Median(f.temperatures_c);
  set.speed_of_sound_mps = SpeedOfSound(set.temperature_c);
  set.num_expected = static_cast<int>(site_.receivers.size());
  set.num_answered = static_cast<int>(f.answers.size());
  set.close_reason = reason;
  set.close_utime = now_utime;

  std::sort(f.answers.begin(), f.answers.end(),
            [](const Answer& a, const Answer& b) { return a.receiver_index < b.receiver_index; });
  int64_t earliest_fire = INT64_MAX;
  for (const Answer& a : f.answers) {
    const Receiver& r = site_.receivers[static_cast<size_t>(a.receiver_index)];
    const double tof_us = a.time_of_flight_ns * 1e-3;
    earliest_fire = std::min(earliest_fire, a.arrival_utime - static_cast<int64_t>(tof_us));
    if (!a.has_range) continue;
    AssembledRange range;
    range.receiver_id = r.id;
    range.receiver_position_m = r.position_m;
    range.time_of_flight_us = tof_us;
    range.range_m = RangeFromTimeOfFlight(tof_us, set.speed_of_sound_mps, r.range_offset_m);
    range.arrival_utime = a.arrival_utime;
    set.ranges.push_back(range);
  }
  if (f.has_announcement) {
    set.fire_utime = f.announcement_utime;
    set.fire_time_from_announcement = true;
  } else {
    set.fire_utime = earliest_fire == INT64_MAX ? f.opened_utime : earliest_fire;
    ++counters_["missing_announcement"];
  }
  state->closed[static_cast<size_t>(Slot(f.seq))] = f.seq;
  state->open.erase(state->open.begin() + static_cast<std::ptrdiff_t>(index));
  ++counters_["sets_published"];
  ++counters_[std::string("sets_") + CloseReasonName(reason)];
  closed->push_back(std::move(set));
}

void RangeAssembler::Advance(int64_t now_utime, std::vector<AssembledSet>* closed) {
  for (BeaconState& state : beacons_) {
    // Oldest first, so that sets leave in firing order when several expire
    // together.
    while (true) {
      size_t pick = state.open.size();
      for (size_t i = 0; i < state.open.size(); ++i) {
        if (state.open[i].deadline_utime > now_utime) continue;
        if (pick == state.open.size() || state.open[i].seq < state.open[pick].seq) pick = i;
      }
      if (pick == state.open.size()) break;
      Close(&state, pick, CloseReason::kDeadline, now_utime, closed);
    }
  }
}

void RangeAssembler::Flush(int64_t now_utime, std::vector<AssembledSet>* closed) {
  for (BeaconState& state : beacons_) {
    while (!state.open.empty()) {
      size_t pick = 0;
      for (size_t i = 1; i < state.open.size(); ++i) {
        if (state.open[i].seq < state.open[pick].seq) pick = i;
      }
      Close(&state, pick, CloseReason::kFlushed, now_utime, closed);
    }
  }
}

int64_t RangeAssembler::NextDeadlineUtime() const {
  int64_t next = INT64_MAX;
  for (const BeaconState& state : beacons_) {
    for (const OpenFiring& f : state.open) next = std::min(next, f.deadline_utime);
  }
  return next;
}

}  // namespace roomfix::radio
