#ifndef ROOMFIX_SIM_WALL_DEVICES_H_
#define ROOMFIX_SIM_WALL_DEVICES_H_

#include <cstdint>
#include <map>
#include <queue>
#include <random>
#include <string>
#include <vector>

#include "core/radio/xbee_frame.h"
#include "core/world/site.h"
#include "core/world/ultrasound_model.h"
#include "sim/shared_air.h"

namespace roomfix {

// What goes wrong between the wall devices and the coordinator's serial
// port: the faults that sank the reference's dynamic test, and worse.
// Probabilities are per report (or per frame, per byte where said).
struct RadioFaults {
  // The ultrasound itself: Gaussian noise, non-line-of-sight detours, and
  // receivers that hear nothing (they send a no-echo report).
  UltrasoundNoise ultrasound;
  // The radio loses a report or an announcement.
  double lost_report_probability = 0.0;
  double lost_announcement_probability = 0.0;
  // A receiver's module starts buffering: it holds this and every later
  // report until a release time up to buffer_hold_max_s away, then sends
  // them back to back (the reference's bursts under 30 ms apart).
  double buffer_probability = 0.0;
  double buffer_hold_max_s = 0.15;
  // A report is delayed by one to three firing periods, so it arrives among
  // a later firing's reports.
  double reorder_probability = 0.0;
  // A report is sent twice.
  double duplicate_probability = 0.0;
  // Per firing: a report for it from a module that is not in the site (a
  // neighbour's network), with a plausible payload.
  double foreign_probability = 0.0;
  // Per byte on the serial line: one bit flipped.
  double corrupt_byte_probability = 0.0;
  // Per frame: a run of 1-20 random bytes written before it.
  double garbage_probability = 0.0;
  // The beacon's own module delays an announcement by up to
  // announcement_delay_max_s, so that it may arrive after reports.
  double announcement_delay_probability = 0.0;
  double announcement_delay_max_s = 0.03;
  // Every restart_every_s (0: never) the beacon is switched off for
  // restart_pause_s and comes back counting its firings from 0 again.
  double restart_every_s = 0.0;
  double restart_pause_s = 1.0;

  bool IsValid(std::string* error) const;
  // Every fault at a high rate, for stress tests and `--faults all`.
  static RadioFaults All();
};

struct WallDevicesOptions {
  // Firings per second of each beacon: under the TDMA schedule at most one
  // per frame of (site beacons x slot), docs/radio_protocol.md.
  double rate_hz = 10.0;
  // When the beacons fire (site-file TDMA table or free-running), their
  // crystals, and whether their pulses collide (core/world/air_model.h).
  FiringPlanOptions::Mode schedule = FiringPlanOptions::Mode::kTdma;
  double clock_ppm = 50.0;
  bool collisions = true;
  // The coordinator played (site `radios[].id`): only its receivers' reports
  // are written; every beacon's announcement is (it is a broadcast each
  // coordinator hears). 0: every receiver.
  int radio_id = 0;
  radio::ApiMode api_mode = radio::ApiMode::kEscaped;
  // 0x90 (ZigBee receive packet) or 0x80 (802.15.4, 64-bit source).
  uint8_t frame_type = radio::kZigbeeRxFrameType;
  // Time from a device handing a message to its radio to the coordinator's
  // serial port: uniform in [min, max].
  double radio_latency_min_s = 0.002;
  double radio_latency_max_s = 0.006;
  // Time a receiver takes from the echo to handing its report over.
  double processing_s = 0.001;
  RadioFaults faults;
  uint64_t seed = 1;
  // Host time that is t = 0 of the trajectories (shared with the ground
  // truth, so both describe the same motion).
  int64_t start_utime = 0;
  // The 16-bit firing number of the first firing (tests start near 65535 to
  // cross the wrap-around).
  uint16_t first_seq = 0;
  // Keep a FiringRecord per firing (tests); a long-running simulator turns
  // it off, or the ledger grows by about 10 MB an hour.
  bool keep_ledger = true;

  bool IsValid(std::string* error) const;
};

// What the virtual devices did for one firing: the ground truth a test
// checks the bridge's range sets against.
struct FiringRecord {
  int beacon_id = 0;
  // The firing count since the simulation started, 0 first; the radio
  // carries a 16-bit number that starts at first_seq and again at 0 after
  // each restart.
  int64_t seq = 0;
  uint16_t radio_seq = 0;
  // The first firing after a restart of the beacon.
  bool after_restart = false;
  int64_t fire_utime = 0;
  // When the announcement's last byte is written; -1 when lost.
  int64_t announcement_utime = -1;
  bool announcement_intact = true;
  struct Report {
    int receiver_id = 0;
    uint32_t time_of_flight_ns = 0;
    bool no_echo = false;
    // When the first copy's last byte is written; -1 when the radio lost it.
    int64_t delivery_utime = -1;
    // False when a byte of its frame was corrupted on the serial line.
    bool intact = true;
    // What the receiver's detector made of the air (kEarly, kArmedInTail:
    // another pulse's sound was timed, the time of flight is wrong).
    Detection::Kind air = Detection::Kind::kOwn;
  };
  std::vector<Report> reports;
  // Payload time of flight of reports sent from foreign addresses.
  std::vector<uint32_t> foreign_time_of_flight_ns;
};

// The beacon and the wall receivers of a site, as the bytes a coordinator
// would write to its serial port: announcements and range reports in XBee
// API frames (docs/radio_protocol.md), times of flight from the simulated
// robots' true trajectories and the site geometry, with RadioFaults applied.
//
// Pure and deterministic: Advance(now) returns the bytes due by `now`
// (a pseudo-terminal writer or a test feeds them on), and the same seed and
// times give the same bytes.
class VirtualWallDevices {
 public:
  VirtualWallDevices(const Site& site, const WallDevicesOptions& options);

  // Simulates every firing up to now_utime and appends the bytes whose
  // delivery time is at or before now_utime, in delivery order.
  void Advance(int64_t now_utime, std::vector<uint8_t>* bytes);
  // As Advance, but one chunk per delivery time (for tests that stamp each
  // chunk with its own arrival).
  struct Chunk {
    int64_t utime = 0;
    std::vector<uint8_t> bytes;
  };
  void AdvanceChunks(int64_t now_utime, std::vector<Chunk>* chunks);
  // When the next bytes are due, or INT64_MAX.
  int64_t NextDeliveryUtime() const;

  // Every firing simulated so far, by (beacon id, seq).
  const std::map<std::pair<int, int64_t>, FiringRecord>& ledger() const { return ledger_; }
  int64_t firings() const { return firings_; }
  int64_t frames_written() const { return frames_written_; }
  // Delivery times of frames with a corrupted byte and of garbage runs: in
  // API mode 1 such bytes can hold up the decoding of the frames after them
  // (a corrupted length makes the decoder wait for bytes that belong to the
  // next frames).
  const std::vector<int64_t>& disturbance_utimes() const { return disturbance_utimes_; }
  // The shared air: schedule, decay, collision counters.
  const SharedAir& air() const { return air_; }
  // The foreign module's address used for foreign reports.
  static constexpr uint64_t kForeignAddress = 0x0013A200F0F0F0F0ull;

 private:
  struct Firer {
    const Beacon* beacon;
    const Trajectory* trajectory;
    // Firings made (including those of restart pauses), and the number on
    // the radio.
    int64_t next_seq = 0;
    uint16_t radio_seq = 0;
    bool restarted = false;
  };
  struct Pending {
    int64_t utime;
    uint64_t order;
    std::vector<uint8_t> bytes;
    bool operator>(const Pending& o) const {
      return utime != o.utime ? utime > o.utime : order > o.order;
    }
  };

  void Fire(Firer* firer, const SharedAir::Firing& firing);
  // Sends a receiver's report (site order), ready at ready_utime, through
  // the radio and its faults (reordering, a module holding reports back,
  // loss, duplicates); fills the report's delivery time and intactness.
  void SendReport(size_t receiver_index, int64_t ready_utime, const std::vector<uint8_t>& payload,
                  FiringRecord::Report* report);
  static std::vector<Firer> MakeFirers(const Site& site, uint16_t first_seq);
  // Frames a payload from a source and queues it for utime; returns false
  // when a byte of it was corrupted on the way.
  bool Schedule(int64_t utime, uint64_t source_address, uint16_t source16,
                const std::vector<uint8_t>& payload);
  double Uniform(double lo, double hi);
  bool Chance(double p);
  int64_t RadioLatencyUs();

  const Site& site_;
  WallDevicesOptions options_;
  std::mt19937_64 rng_;
  std::vector<Firer> firers_;
  SharedAir air_;
  // Per receiver (site order): until when its module holds reports back.
  std::vector<int64_t> hold_until_utime_;
  std::priority_queue<Pending, std::vector<Pending>, std::greater<Pending>> queue_;
  uint64_t order_ = 0;
  std::map<std::pair<int, int64_t>, FiringRecord> ledger_;
  int64_t firings_ = 0;
  int64_t frames_written_ = 0;
  std::vector<int64_t> disturbance_utimes_;
};

}  // namespace roomfix

#endif  // ROOMFIX_SIM_WALL_DEVICES_H_
