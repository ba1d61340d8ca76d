// Fuzz target: the wall devices' payload decoder and the range assembler.
//
// The input is a sequence of packets, each
//   source (1 byte: beacon, receiver 1-4 or a foreign module), time step
//   (1 byte, ms), payload length (1 byte), payload bytes;
// the payloads are mostly garbage, and every fifth is rebuilt into a valid
// message with fields taken from the input, so the assembler sees real
// traffic too. Invariants (abort() on violation):
//  - a decoded payload re-encodes to exactly its bytes;
//  - no firing of a beacon is published twice, and published firing numbers
//    stay unique;
//  - a set holds each receiver at most once, only site receivers, with
//    finite ranges inside what the room allows;
//  - every set leaves by the time its deadline has passed.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <set>
#include <string>
#include <vector>

#include "core/radio/range_assembler.h"
#include "core/radio/wall_payload.h"
#include "core/world/site.h"

namespace {

using roomfix::radio::AssembledSet;
using roomfix::radio::RadioPacket;
using roomfix::radio::WallMessage;

constexpr char kSite[] = R"(
name: fuzz_room
room: {size_m: [4.0, 3.0], height_m: 3.3}
receivers:
  - {id: 1, address: "0x0013A20041000001", position_m: [0.0, 0.0, 2.5]}
  - {id: 2, address: "0x0013A20041000002", position_m: [4.0, 0.0, 2.5], range_offset_m: 0.05}
  - {id: 3, address: "0x0013A20041000003", position_m: [4.0, 3.0, 2.5]}
  - {id: 4, address: "0x0013A20041000004", position_m: [0.0, 3.0, 2.5]}
beacons:
  - {id: 1, address: "0x0013A20042000001", height_m: 1.3}
  - {id: 2, address: "0x0013A20042000002", height_m: 0.5}
)";

const roomfix::Site& FuzzSite() {
  static const roomfix::Site* site = [] {
    auto* s = new roomfix::Site;
    std::string error;
    if (!roomfix::ParseSite(kSite, "fuzz_site", ".", s, &error)) std::abort();
    return s;
  }();
  return *site;
}

void Check(bool ok) {
  if (!ok) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const roomfix::Site& site = FuzzSite();
  roomfix::radio::AssemblerOptions options;
  options.stale_window_firings = 8;
  options.max_open_firings = 4;
  roomfix::radio::RangeAssembler assembler(site, options);
  std::vector<AssembledSet> closed;
  std::set<std::pair<int, int64_t>> published;
  int64_t now = 1'000'000'000;
  const auto deadline_us = static_cast<int64_t>(options.deadline_s * 1e6);

  auto check_closed = [&] {
    for (const AssembledSet& set : closed) {
      Check(published.insert({set.beacon_id, set.firing_seq}).second);
      Check(set.ranges.size() <= site.receivers.size());
      Check(set.num_answered >= static_cast<int>(set.ranges.size()));
      std::set<int> receivers;
      for (const auto& r : set.ranges) {
        Check(receivers.insert(r.receiver_id).second);
        Check(site.FindReceiver(r.receiver_id) != nullptr);
        Check(std::isfinite(r.range_m) && r.range_m > -1.0 && r.range_m < 10.0);
      }
      Check(std::isfinite(set.speed_of_sound_mps) && set.speed_of_sound_mps > 300.0);
    }
    closed.clear();
  };

  size_t i = 0;
  int packet_index = 0;
  while (i + 3 <= size) {
    const uint8_t source = data[i];
    now += data[i + 1] * 1000;
    size_t length = data[i + 2];
    i += 3;
    length = std::min(length, size - i);
    std::vector<uint8_t> payload(data + i, data + i + length);
    i += length;

    WallMessage decoded;
    if (roomfix::radio::DecodeWallMessage(payload.data(), payload.size(), &decoded) ==
        roomfix::radio::PayloadError::kOk) {
      Check(roomfix::radio::EncodeWallMessage(decoded) == payload);
    }
    if (++packet_index % 5 == 0 && payload.size() >= 7) {
      // A well-formed message from the input's bytes.
      WallMessage m;
      m.type = (payload[0] & 1) ? roomfix::radio::PayloadType::kFiring
                                : roomfix::radio::PayloadType::kRangeReport;
      m.beacon_id = static_cast<uint8_t>(1 + payload[1] % 3);
      m.firing_seq = static_cast<uint16_t>(payload[2] << 8 | payload[3]);
      m.time_of_flight_ns =
          static_cast<uint32_t>(payload[4] << 16 | payload[5] << 8 | payload[6]) * 16u;
      m.temperature_centi_c = static_cast<int16_t>(payload[5] << 8 | payload[4]);
      m.flags = payload[6];
      payload = roomfix::radio::EncodeWallMessage(m);
    }

    RadioPacket p;
    const int who = source % 8;
    if (who < 2) {
      p.has_address64 = true;
      p.address64 = site.beacons[static_cast<size_t>(who)].address;
    } else if (who < 6) {
      p.has_address64 = true;
      p.address64 = site.receivers[static_cast<size_t>(who - 2)].address;
    } else if (who == 6) {
      p.has_address64 = true;
      p.address64 = 0x0013A200F0F0F0F0ull;
    } else {
      p.has_address16 = true;
      p.address16 = source;
    }
    p.payload = payload.data();
    p.payload_size = payload.size();
    p.arrival_utime = now;
    assembler.OnPacket(p, &closed);
    check_closed();
    if (source & 0x80) {
      assembler.Advance(now, &closed);
      check_closed();
      Check(assembler.NextDeadlineUtime() > now);
    }
  }
  assembler.Advance(now + deadline_us, &closed);
  check_closed();
  Check(assembler.open_firings() == 0);
  return 0;
}
