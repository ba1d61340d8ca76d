#include "sim/wall_devices.h"

#include <cmath>

#include "core/radio/wall_payload.h"

namespace roomfix {
namespace {

bool IsProbability(double p) { return p >= 0.0 && p <= 1.0; }

// A stable 16-bit network address per device, as a ZigBee network would
// assign; only 0x90 frames carry it and the bridge does not rely on it.
uint16_t ShortAddress(uint64_t address64) {
  return static_cast<uint16_t>((address64 ^ (address64 >> 16) ^ (address64 >> 32)) & 0xFFF7);
}

}  // namespace

bool RadioFaults::IsValid(std::string* error) const {
  const std::pair<const char*, double> probabilities[] = {
      {"lost report", lost_report_probability},
      {"lost announcement", lost_announcement_probability},
      {"buffer", buffer_probability},
      {"reorder", reorder_probability},
      {"duplicate", duplicate_probability},
      {"foreign", foreign_probability},
      {"corrupt byte", corrupt_byte_probability},
      {"garbage", garbage_probability}};
  for (const auto& [name, p] : probabilities) {
    if (!IsProbability(p)) {
      *error = std::string(name) + " probability must be in [0, 1]";
      return false;
    }
  }
  if (!IsProbability(announcement_delay_probability) ||
      !(announcement_delay_max_s > 0.0 && announcement_delay_max_s <= 1.0)) {
    *error = "announcement delay: probability in [0, 1], delay in (0, 1] s";
    return false;
  }
  if (!(restart_every_s >= 0.0) || !(restart_pause_s > 0.0 && restart_pause_s < 3600.0) ||
      (restart_every_s > 0.0 && restart_every_s <= restart_pause_s)) {
    *error = "restarts: every > pause > 0 s (every 0: never)";
    return false;
  }
  if (!(buffer_hold_max_s > 0.0 && buffer_hold_max_s <= 10.0)) {
    *error = "buffer hold must be in (0, 10] s";
    return false;
  }
  return ultrasound.IsValid(error);
}

RadioFaults RadioFaults::All() {
  RadioFaults f;
  f.ultrasound.sigma_m = 0.01;
  f.ultrasound.nlos_probability = 0.05;
  f.ultrasound.dropout_probability = 0.05;
  f.lost_report_probability = 0.05;
  f.lost_announcement_probability = 0.05;
  f.buffer_probability = 0.1;
  f.reorder_probability = 0.05;
  f.duplicate_probability = 0.1;
  f.foreign_probability = 0.2;
  f.corrupt_byte_probability = 0.001;
  f.garbage_probability = 0.05;
  f.announcement_delay_probability = 0.05;
  return f;
}

bool WallDevicesOptions::IsValid(std::string* error) const {
  if (!(rate_hz > 0.0 && rate_hz <= 1000.0)) {
    *error = "firing rate must be in (0, 1000] Hz";
    return false;
  }
  if (frame_type != radio::kZigbeeRxFrameType && frame_type != radio::kRx64FrameType) {
    *error = "frame type must be 0x90 or 0x80";
    return false;
  }
  if (!(radio_latency_min_s >= 0.0 && radio_latency_min_s <= radio_latency_max_s &&
        radio_latency_max_s <= 1.0)) {
    *error = "radio latency must satisfy 0 <= min <= max <= 1 s";
    return false;
  }
  if (!(processing_s >= 0.0 && processing_s <= 1.0)) {
    *error = "processing time must be in [0, 1] s";
    return false;
  }
  if (!(clock_ppm >= 0.0 && clock_ppm <= 10000.0)) {
    *error = "beacon clock error must be in [0, 10000] ppm";
    return false;
  }
  if (radio_id < 0) {
    *error = "radio id must not be negative";
    return false;
  }
  return faults.IsValid(error);
}

std::vector<VirtualWallDevices::Firer> VirtualWallDevices::MakeFirers(const Site& site,
                                                                      uint16_t first_seq) {
  std::vector<Firer> firers;
  for (const CarriedBeacon& b : CarriedBeacons(site)) {
    Firer f{b.beacon, b.trajectory};
    f.radio_seq = first_seq;
    firers.push_back(f);
  }
  return firers;
}

namespace {

SharedAirOptions AirOptions(const WallDevicesOptions& o) {
  SharedAirOptions air;
  air.mode = o.schedule;
  air.rate_hz = o.rate_hz;
  air.clock_ppm = o.clock_ppm;
  air.collisions = o.collisions;
  // A beacon that misses an announcement on the radio keeps its own time.
  air.sync_loss_probability = o.faults.lost_announcement_probability;
  air.seed = o.seed;
  air.start_utime = o.start_utime;
  return air;
}

}  // namespace

VirtualWallDevices::VirtualWallDevices(const Site& site, const WallDevicesOptions& options)
    : site_(site),
      options_(options),
      rng_(options.seed),
      firers_(MakeFirers(site, options.first_seq)),
      air_(site, CarriedBeacons(site), AirOptions(options)) {
  hold_until_utime_.assign(site.receivers.size(), INT64_MIN);
}

double VirtualWallDevices::Uniform(double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng_);
}

bool VirtualWallDevices::Chance(double p) { return p > 0.0 && Uniform(0.0, 1.0) < p; }

int64_t VirtualWallDevices::RadioLatencyUs() {
  return static_cast<int64_t>(
      std::llround(Uniform(options_.radio_latency_min_s, options_.radio_latency_max_s) * 1e6));
}

bool VirtualWallDevices::Schedule(int64_t utime, uint64_t source_address, uint16_t source16,
                                  const std::vector<uint8_t>& payload) {
  radio::ReceivePacket packet;
  packet.frame_type = options_.frame_type;
  packet.has_address64 = true;
  packet.address64 = source_address;
  if (options_.frame_type == radio::kZigbeeRxFrameType) {
    packet.has_address16 = true;
    packet.address16 = source16;
    packet.options = 0x01;  // acknowledged
  } else {
    packet.has_rssi = true;
    packet.rssi_dbm = -static_cast<int>(Uniform(40.0, 80.0));
  }
  packet.payload = payload;
  const std::vector<uint8_t> data = radio::EncodeReceivePacket(packet);
  Pending p{utime, order_++, {}};
  if (Chance(options_.faults.garbage_probability)) {
    const int n = static_cast<int>(Uniform(1.0, 21.0));
    for (int i = 0; i < n; ++i) p.bytes.push_back(static_cast<uint8_t>(rng_() & 0xFF));
    if (options_.keep_ledger) disturbance_utimes_.push_back(utime);
  }
  const size_t frame_start = p.bytes.size();
  radio::AppendFrame(data.data(), data.size(), options_.api_mode, &p.bytes);
  bool intact = true;
  if (options_.faults.corrupt_byte_probability > 0.0) {
    for (size_t i = frame_start; i < p.bytes.size(); ++i) {
      if (Chance(options_.faults.corrupt_byte_probability)) {
        p.bytes[i] ^= static_cast<uint8_t>(1u << (rng_() % 8));
        intact = false;
      }
    }
  }
  if (!intact && options_.keep_ledger) disturbance_utimes_.push_back(utime);
  queue_.push(std::move(p));
  ++frames_written_;
  return intact;
}

void VirtualWallDevices::SendReport(size_t receiver_index, int64_t ready_utime,
                                    const std::vector<uint8_t>& payload,
                                    FiringRecord::Report* report) {
  const RadioFaults& faults = options_.faults;
  const Receiver& receiver = site_.receivers[receiver_index];
  int64_t utime = ready_utime + RadioLatencyUs();
  if (Chance(faults.reorder_probability)) {
    utime += static_cast<int64_t>(air_.frame_s() * 1e6 * Uniform(1.0, 3.0));
  }
  int64_t& hold = hold_until_utime_[receiver_index];
  if (utime < hold) {
    utime = hold;
  } else if (Chance(faults.buffer_probability)) {
    hold = utime + static_cast<int64_t>(Uniform(0.0, faults.buffer_hold_max_s) * 1e6);
    utime = hold;
  }
  if (!Chance(faults.lost_report_probability)) {
    const uint16_t source16 = ShortAddress(receiver.address);
    report->delivery_utime = utime;
    report->intact = Schedule(utime, receiver.address, source16, payload);
    if (Chance(faults.duplicate_probability)) {
      Schedule(utime + RadioLatencyUs(), receiver.address, source16, payload);
    }
  }
}

void VirtualWallDevices::Fire(Firer* firer, const SharedAir::Firing& firing) {
  const int64_t fire_utime = firing.fire_utime;
  const RadioFaults& faults = options_.faults;
  FiringRecord record;
  record.beacon_id = firer->beacon->id;
  record.seq = firer->next_seq;
  record.radio_seq = firer->radio_seq;
  record.after_restart = firer->restarted;
  firer->restarted = false;
  record.fire_utime = fire_utime;
  const uint16_t seq16 = firer->radio_seq;
  const double temperature_c = site_.simulation.temperature_c;
  const int16_t temperature_centi_c = radio::TemperatureToCentiC(temperature_c);

  radio::WallMessage announce;
  announce.type = radio::PayloadType::kFiring;
  announce.beacon_id = static_cast<uint8_t>(firer->beacon->id);
  announce.firing_seq = seq16;
  announce.temperature_centi_c = temperature_centi_c;
  if (!Chance(faults.lost_announcement_probability)) {
    record.announcement_utime = fire_utime + RadioLatencyUs();
    if (Chance(faults.announcement_delay_probability)) {
      record.announcement_utime +=
          static_cast<int64_t>(Uniform(0.0, faults.announcement_delay_max_s) * 1e6);
    }
    record.announcement_intact =
        Schedule(record.announcement_utime, firer->beacon->address,
                 ShortAddress(firer->beacon->address), radio::EncodeWallMessage(announce));
  }

  const double t_s = (fire_utime - options_.start_utime) * 1e-6;
  const GroundTruthPose truth = firer->trajectory->PoseAt(t_s);
  // Dropouts are simulated here, not in SimulateRanges: a receiver that hears
  // nothing still answers, with a no-echo report.
  UltrasoundNoise noise = faults.ultrasound;
  noise.dropout_probability = 0.0;
  const std::vector<SimulatedRange> ranges = SimulateRangesAt(
      site_, t_s, {truth.x_m, truth.y_m, firer->beacon->height_m}, temperature_c, noise, &rng_);
  // What each receiver's detector times among the other beacons' pulses, in
  // site receiver order; NaN for a receiver no audible path reaches (an
  // obstacle in the way, core/world/acoustic_paths.h), which answers no echo.
  std::vector<double> own_tof_s(site_.receivers.size(), std::nan(""));
  for (const SimulatedRange& r : ranges) {
    const Receiver* receiver = site_.FindReceiver(r.receiver_id);
    own_tof_s[static_cast<size_t>(receiver - site_.receivers.data())] = r.time_of_flight_s;
  }
  const std::vector<Detection> detections = air_.Detect(firing, own_tof_s);
  for (size_t i = 0; i < site_.receivers.size(); ++i) {
    const Receiver& receiver = site_.receivers[i];
    const size_t receiver_index = i;
    // A receiver on another coordinator's network: another pty carries it.
    const bool on_this_radio = options_.radio_id == 0 ||
                               site_.RadioOfReceiver(receiver.id) == nullptr ||
                               site_.RadioOfReceiver(receiver.id)->id == options_.radio_id;
    FiringRecord::Report report;
    report.receiver_id = receiver.id;
    report.air = detections[i].kind;
    // A dropout (the receiver missed its own pulse) turns an own detection
    // into no echo; a detector already set off by another pulse stays so.
    const bool dropout = Chance(faults.ultrasound.dropout_probability);
    report.no_echo = detections[i].kind == Detection::Kind::kNone ||
                     (dropout && detections[i].kind == Detection::Kind::kOwn);
    if (report.no_echo) report.air = Detection::Kind::kNone;
    report.time_of_flight_ns =
        report.no_echo ? 0 : radio::TimeOfFlightToNs(detections[i].time_of_flight_s);
    if (!on_this_radio) continue;

    radio::WallMessage m;
    m.type = radio::PayloadType::kRangeReport;
    m.beacon_id = announce.beacon_id;
    m.firing_seq = seq16;
    m.time_of_flight_ns = report.time_of_flight_ns;
    m.temperature_centi_c = temperature_centi_c;
    m.flags = report.no_echo ? radio::kFlagNoEcho : 0;
    const std::vector<uint8_t> payload = radio::EncodeWallMessage(m);

    // A receiver that heard nothing reports when its listening window ends.
    const double heard_after_s =
        report.no_echo ? air_.decay().listen_s : detections[i].time_of_flight_s;
    const int64_t ready_utime =
        fire_utime +
        static_cast<int64_t>(std::llround((heard_after_s + options_.processing_s) * 1e6));
    SendReport(receiver_index, ready_utime, payload, &report);
    record.reports.push_back(report);
  }

  if (Chance(faults.foreign_probability)) {
    // A neighbour's receiver answering the same beacon id and firing number:
    // only its address gives it away.
    radio::WallMessage m;
    m.type = radio::PayloadType::kRangeReport;
    m.beacon_id = announce.beacon_id;
    m.firing_seq = seq16;
    m.time_of_flight_ns = radio::TimeOfFlightToNs(Uniform(0.004, 0.012));
    m.temperature_centi_c = temperature_centi_c;
    record.foreign_time_of_flight_ns.push_back(m.time_of_flight_ns);
    Schedule(fire_utime + static_cast<int64_t>(Uniform(0.005, 0.03) * 1e6), kForeignAddress,
             ShortAddress(kForeignAddress), radio::EncodeWallMessage(m));
  }
  if (options_.keep_ledger) ledger_[{record.beacon_id, record.seq}] = std::move(record);
  ++firer->next_seq;
  ++firer->radio_seq;
  ++firings_;
}

void VirtualWallDevices::AdvanceChunks(int64_t now_utime, std::vector<Chunk>* chunks) {
  const RadioFaults& faults = options_.faults;
  // Within each restart period the beacon is off for the last
  // restart_pause_s; it comes back counting from 0.
  auto off = [&](size_t, int64_t utime) {
    if (faults.restart_every_s <= 0.0) return false;
    const double t_s = (utime - options_.start_utime) * 1e-6;
    return std::fmod(t_s, faults.restart_every_s) >=
           faults.restart_every_s - faults.restart_pause_s;
  };
  for (const SharedAir::Firing& firing : air_.TakeDue(now_utime, off)) {
    Firer& f = firers_[firing.firer];
    // Firings skipped while the process was not running still count.
    f.next_seq += firing.skipped_before;
    f.radio_seq =
        static_cast<uint16_t>(f.radio_seq + static_cast<uint16_t>(firing.skipped_before & 0xFFFF));
    if (firing.silent) {
      f.radio_seq = 0;
      f.restarted = true;
      continue;
    }
    Fire(&f, firing);
  }
  while (!queue_.empty() && queue_.top().utime <= now_utime) {
    // priority_queue::top is const; the bytes are copied out before pop.
    Chunk chunk{queue_.top().utime, queue_.top().bytes};
    queue_.pop();
    if (!chunks->empty() && chunks->back().utime == chunk.utime) {
      chunks->back().bytes.insert(chunks->back().bytes.end(), chunk.bytes.begin(),
                                  chunk.bytes.end());
    } else {
      chunks->push_back(std::move(chunk));
    }
  }
}

void VirtualWallDevices::Advance(int64_t now_utime, std::vector<uint8_t>* bytes) {
  std::vector<Chunk> chunks;
  AdvanceChunks(now_utime, &chunks);
  for (const Chunk& c : chunks) bytes->insert(bytes->end(), c.bytes.begin(), c.bytes.end());
}

int64_t VirtualWallDevices::NextDeliveryUtime() const {
  return queue_.empty() ? INT64_MAX : queue_.top().utime;
}

}  // namespace roomfix
