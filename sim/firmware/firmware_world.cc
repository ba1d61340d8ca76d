#include "sim/firmware/firmware_world.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>

#include "core/world/trajectory.h"
#include "core/world/ultrasound_model.h"

namespace roomfix::firmware {

namespace {

constexpr uint64_t kBroadcast64 = 0x000000000000FFFFull;
// XBee API frame types a device's firmware may send its module, and the
// module's answers (Digi's 802.15.4 and ZigBee user guides).
constexpr uint8_t kTx64Request = 0x00;
constexpr uint8_t kTx16Request = 0x01;
constexpr uint16_t kBroadcast16 = 0xFFFF;
constexpr uint8_t kAtCommand = 0x08;
constexpr uint8_t kZigbeeTxRequest = 0x10;
constexpr uint8_t kAtResponse = 0x88;
constexpr uint8_t kTxStatus802 = 0x89;
constexpr uint8_t kZigbeeTxStatus = 0x8B;
// A pulse starts at the first burst-pin edge after this long without one
// (a 40 kHz burst toggles every 12.5 us).
constexpr double kBurstQuietS = 1e-3;
// RSSI the coordinator's 0x80 frames report (-40 dBm: a room-sized link).
constexpr int kRssiDbm = -40;
// A device's UART more than this far off its module's BD gets framing
// errors (the UART samples mid-bit: half a bit over ten bits).
constexpr double kMaxBaudError = 0.045;

uint64_t ReadBe64(const uint8_t* p) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | p[i];
  return v;
}

class CollectingSink : public radio::FrameSink {
 public:
  void OnFrame(const uint8_t* frame_data, size_t size, uint64_t) override {
    frames.emplace_back(frame_data, frame_data + size);
  }
  void OnFrameError(const radio::FrameErrorInfo&) override { ++errors; }
  std::vector<std::vector<uint8_t>> frames;
  int64_t errors = 0;
};

double Distance(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                   (a[2] - b[2]) * (a[2] - b[2]));
}

// The angle between a receiver's axis (towards the floor's middle, where it
// is aimed) and the direction a pulse arrives from, rad.
double OffAxisRad(const std::array<double, 3>& receiver_m, const std::array<double, 3>& source_m,
                  const std::array<double, 3>& aim_m) {
  const double leg = Distance(source_m, receiver_m);
  const double axis = Distance(aim_m, receiver_m);
  if (!(leg > 0 && axis > 0)) return 0.0;
  double dot = 0.0;
  for (int k = 0; k < 3; ++k) dot += (source_m[k] - receiver_m[k]) * (aim_m[k] - receiver_m[k]);
  return std::acos(std::clamp(dot / (leg * axis), -1.0, 1.0));
}

}  // namespace

bool DetectorModel::IsValid(std::string* error) const {
  if (!(rise_tau_s > 0 && rise_tau_s < 1e-2 && off_axis_db_per_rad2 >= 0 &&
        strong_margin_db >= 0)) {
    *error =
        "detector: need 0 < rise_tau_s < 10 ms, off_axis_db_per_rad2 >= 0, "
        "strong_margin_db >= 0";
    return false;
  }
  return true;
}

bool RadioFaultOptions::IsValid(std::string* error) const {
  if (!(loss_probability >= 0 && loss_probability <= 1 && buffer_probability >= 0 &&
        buffer_probability <= 1 && buffer_hold_max_s >= 0)) {
    *error = "radio faults: probabilities in [0, 1], buffer_hold_max_s >= 0";
    return false;
  }
  return true;
}

bool FirmwareWorldOptions::IsValid(std::string* error) const {
  if (beacon_elf.empty() || receiver_elf.empty()) {
    *error = "need both firmware ELF files (beacon and receiver)";
    return false;
  }
  if (!detector.IsValid(error) || !faults.IsValid(error)) return false;
  std::string why;
  if (!xbee.IsValid(&why)) {
    *error = "xbee: " + why;
    return false;
  }
  if (!(coordinator_baud >= 1200 && device_baud >= 1200)) {
    *error = "baud rates must be at least 1200";
    return false;
  }
  // The lookahead (firmware_world.h): the shortest cross-device delay is a
  // UART byte plus the module's processing, over 0.3 ms; a quantum shorter
  // keeps every delivery exact.
  if (quantum_cycles < 1 || quantum_cycles > frequency_hz / 4000) {
    *error = "quantum_cycles must be in [1, f / 4000] (at most 250 us)";
    return false;
  }
  for (const Reboot& r : reboots) {
    if (!(r.at_s >= 0)) {
      *error = "reboot times must not be negative";
      return false;
    }
  }
  return true;
}

struct FirmwareWorld::Module {
  uint64_t address = 0;
  bool coordinator = false;
  radio::FrameDecoder decoder;
  // The device-to-module line is busy until this cycle; the module-to-
  // device line likewise.
  uint64_t line_in_free = 0;
  uint64_t line_out_free = 0;
  // A buffering module holds its frames until this cycle.
  uint64_t hold_until = 0;
  explicit Module(radio::ApiMode mode) : decoder(radio::FrameDecoderOptions{mode, 300}) {}
};

FirmwareWorld::FirmwareWorld(const Site& site, const FirmwareWorldOptions& options)
    : site_(site),
      options_(options),
      decay_(ComputeRoomDecay(site, site.simulation.temperature_c)),
      rng_(options.seed) {
  if (!site.obstacles.empty()) scene_.emplace(site, site.simulation.temperature_c);
}

FirmwareWorld::~FirmwareWorld() = default;

size_t CountFirmwareDevices(const Site& site, int radio_id) {
  size_t n = 0;
  for (const Receiver& r : site.receivers) {
    const RadioNetwork* net = site.RadioOfReceiver(r.id);
    if (radio_id == 0 || net == nullptr || net->id == radio_id) ++n;
  }
  for (const SimulatedRobot& sr : site.simulation.robots) {
    const Robot* robot = site.FindRobot(sr.robot_id);
    if (robot != nullptr && robot->beacon_id) ++n;
  }
  return n;
}

std::unique_ptr<FirmwareWorld> FirmwareWorld::Create(const Site& site,
                                                     const FirmwareWorldOptions& options,
                                                     std::string* error) {
  if (!options.IsValid(error)) return nullptr;
  std::unique_ptr<FirmwareWorld> world(new FirmwareWorld(site, options));
  if (!world->AddDevices(error)) return nullptr;
  for (const Reboot& r : options.reboots) {
    if (r.device >= world->devices_.size()) {
      *error = "reboot of device " + std::to_string(r.device) + ", but there are only " +
               std::to_string(world->devices_.size());
      return nullptr;
    }
    FirmwareWorld* w = world.get();
    world->At(world->Cycles(r.at_s), [w, r] { w->RebootDevice(r.device); });
  }
  return world;
}

bool FirmwareWorld::AddDevices(std::string* error) {
  auto add = [&](Device::Role role, int id, uint64_t address, const std::string& elf,
                 std::vector<uint8_t> eeprom) -> Device* {
    AvrCoreOptions o;
    o.elf_path = elf;
    o.frequency_hz = options_.frequency_hz;
    o.eeprom = std::move(eeprom);
    Device d;
    d.role = role;
    d.id = id;
    d.address = address;
    d.core = AvrCore::Create(o, error);
    if (d.core == nullptr) return nullptr;
    devices_.push_back(std::move(d));
    auto m = std::make_unique<Module>(options_.device_api_mode);
    m->address = address;
    modules_.push_back(std::move(m));
    return &devices_.back();
  };
  for (const Receiver& r : site_.receivers) {
    const RadioNetwork* net = site_.RadioOfReceiver(r.id);
    if (options_.radio_id != 0 && net != nullptr && net->id != options_.radio_id) continue;
    std::vector<uint8_t> ee =
        options_.receiver_eeprom ? options_.receiver_eeprom(r) : std::vector<uint8_t>{};
    Device* d = add(Device::Role::kReceiver, r.id, r.address, options_.receiver_elf, ee);
    if (d == nullptr) return false;
    d->position_m = r.position_m;
  }
  for (const SimulatedRobot& sr : site_.simulation.robots) {
    const Robot* robot = site_.FindRobot(sr.robot_id);
    if (robot == nullptr || !robot->beacon_id) continue;
    const Beacon* b = site_.FindBeacon(*robot->beacon_id);
    if (b == nullptr) continue;
    std::vector<uint8_t> ee =
        options_.beacon_eeprom ? options_.beacon_eeprom(*b) : std::vector<uint8_t>{};
    Device* d = add(Device::Role::kBeacon, b->id, b->address, options_.beacon_elf, ee);
    if (d == nullptr) return false;
    d->trajectory = sr.trajectory.get();
    d->height_m = b->height_m;
  }
  auto coordinator = std::make_unique<Module>(options_.coordinator_api_mode);
  coordinator->coordinator = true;
  coordinator->address = options_.coordinator_address;
  modules_.push_back(std::move(coordinator));
  last_burst_edge_.assign(devices_.size(), -1);
  high_until_.assign(devices_.size(), {0, 0});
  for (size_t i = 0; i < devices_.size(); ++i) {
    AvrCore* core = devices_[i].core.get();
    core->WatchUart([this, i](uint64_t cycle, uint8_t byte) { OnDeviceUart(i, cycle, byte); });
    if (devices_[i].role == Device::Role::kBeacon) {
      // Rising edges only: simavr also reports the pin's level when the
      // firmware first sets its direction.
      core->WatchPin(options_.wiring.burst_pin, [this, i](uint64_t cycle, bool level) {
        if (level) OnBurstEdge(i, cycle);
      });
    }
  }
  return true;
}

uint64_t FirmwareWorld::Cycles(double s) const {
  return static_cast<uint64_t>(std::llround(s * options_.frequency_hz));
}

double FirmwareWorld::Seconds(uint64_t cycle) const {
  return static_cast<double>(cycle) / options_.frequency_hz;
}

double FirmwareWorld::now_s() const { return Seconds(now_cycle_); }

void FirmwareWorld::At(uint64_t cycle, std::function<void()> run) {
  if (cycle < now_cycle_) ++counters_.late_events;
  events_.push(Event{cycle, order_++, std::move(run)});
}

void FirmwareWorld::AdvanceTo(double t_s) {
  const uint64_t target = Cycles(t_s);
  while (now_cycle_ < target) {
    const uint64_t end = std::min(target, now_cycle_ + options_.quantum_cycles);
    // The world's own events of this quantum first: they hand the cores
    // what is due at exact cycles inside it.
    while (!events_.empty() && events_.top().cycle < end) {
      Event e = events_.top();
      events_.pop();
      e.run();
    }
    for (Device& d : devices_) d.core->RunUntil(end);
    now_cycle_ = end;
    channel_.ForgetBefore(Seconds(now_cycle_) - 0.1);
  }
}

int64_t FirmwareWorld::instructions() const {
  int64_t n = 0;
  for (const Device& d : devices_) n += d.core->counters().instructions_run;
  return n;
}

void FirmwareWorld::RebootDevice(size_t index) {
  ++counters_.reboots;
  devices_[index].core->Reset();
  // The detector's levels are the world's: a reset chip sees them as they
  // are, and they fall when their pulse ends.
  last_burst_edge_[index] = -1;
}

void FirmwareWorld::OnDeviceUart(size_t index, uint64_t cycle, uint8_t byte) {
  const AvrCore& core = *devices_[index].core;
  Module& m = *modules_[index];
  const uint64_t byte_cycles = core.uart_byte_cycles();
  if (std::abs(core.uart_baud() / options_.device_baud - 1.0) > kMaxBaudError) {
    // The module samples the wrong bits: what it gets is not this byte.
    ++counters_.baud_mismatches;
    return;
  }
  // simavr hands the byte over as UDR0 is written; its stop bit leaves the
  // pin one frame later, after the bytes queued before it.
  const uint64_t end = std::max(cycle, m.line_in_free) + byte_cycles;
  m.line_in_free = end;
  CollectingSink sink;
  m.decoder.Feed(&byte, 1, &sink);
  counters_.device_frame_errors += sink.errors;
  for (const auto& f : sink.frames) OnModuleFrame(index, end, f.data(), f.size());
}

void FirmwareWorld::FromCoordinator(const uint8_t* data, size_t size) {
  const size_t index = modules_.size() - 1;
  Module& m = *modules_[index];
  CollectingSink sink;
  m.decoder.Feed(data, size, &sink);
  for (const auto& f : sink.frames) {
    ++counters_.frames_from_coordinator;
    OnModuleFrame(index, now_cycle_, f.data(), f.size());
  }
}

void FirmwareWorld::OnModuleFrame(size_t module, uint64_t cycle, const uint8_t* d, size_t size) {
  Module& m = *modules_[module];
  if (!m.coordinator) ++counters_.frames_from_devices;
  std::uniform_real_distribution<double> tx(options_.xbee.tx_processing_min_s,
                                            options_.xbee.tx_processing_max_s);
  uint64_t ready = cycle + Cycles(tx(rng_));
  const uint8_t type = d[0];
  if (type == kAtCommand && size >= 4) {
    // Local AT commands are answered OK (status 0) with no value: the
    // module's settings are the simulation's.
    WriteToModuleUart(module, ready, {kAtResponse, d[1], d[2], d[3], 0x00});
    return;
  }
  // Transmit requests: ZigBee 0x10 (frame id, 64-bit and 16-bit
  // destination, radius, options), 802.15.4 0x00 (frame id, 64-bit
  // destination, options) and 0x01 (frame id, 16-bit destination, options).
  const bool zigbee = type == kZigbeeTxRequest && size >= 14;
  const bool tx64 = type == kTx64Request && size >= 11;
  const bool tx16 = type == kTx16Request && size >= 5;
  if (!zigbee && !tx64 && !tx16) {
    ++counters_.unknown_frame_types;
    return;
  }
  // A buffering module starts holding its frames back.
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  if (!m.coordinator && ready >= m.hold_until && unit(rng_) < options_.faults.buffer_probability) {
    m.hold_until = ready + Cycles(unit(rng_) * options_.faults.buffer_hold_max_s);
  }
  if (ready < m.hold_until) {
    ++counters_.buffered_frames;
    ready = m.hold_until;
  }
  const uint8_t frame_id = d[1];
  // A 16-bit destination other than broadcast names a module by MY, which
  // no module here has (MY = 0xFFFE everywhere): it goes unacknowledged.
  const uint64_t dest =
      tx16 ? (((d[2] << 8) | d[3]) == kBroadcast16 ? kBroadcast64 : ~0ull) : ReadBe64(d + 2);
  const size_t header = zigbee ? 14 : (tx64 ? 11 : 5);
  std::vector<uint8_t> payload(d + header, d + size);
  SendOverAir(module, ready, dest, frame_id, std::move(payload));
}

void FirmwareWorld::SendOverAir(size_t from, uint64_t ready_cycle, uint64_t dest64,
                                uint8_t frame_id, std::vector<uint8_t> payload) {
  const bool broadcast = dest64 == kBroadcast64;
  const double air_s = AirTimeS(static_cast<int>(payload.size()), broadcast);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  uint8_t status = 0x00;
  int retries = 0;
  Transmission t = Transmit(Seconds(ready_cycle), air_s, options_.xbee, &channel_, &rng_);
  if (!t.sent) {
    ++counters_.csma_failures;
    status = 0x02;
  } else if (broadcast) {
    ++counters_.broadcasts;
    for (size_t to = 0; to < modules_.size(); ++to) {
      if (to == from) continue;
      if (unit(rng_) < options_.faults.loss_probability) {
        ++counters_.lost_receptions;
        continue;
      }
      Receive(to, from, Cycles(t.end_s), true, payload);
    }
  } else {
    ++counters_.unicasts;
    size_t to = modules_.size();
    for (size_t k = 0; k < modules_.size(); ++k) {
      if (k != from && modules_[k]->address == dest64) to = k;
    }
    // The MAC retries until an ACK comes back (a lost frame or a lost ACK
    // look alike to the sender), up to max_frame_retries times.
    for (;;) {
      const bool heard = to < modules_.size() && unit(rng_) >= options_.faults.loss_probability;
      if (heard) {
        Receive(to, from, Cycles(t.end_s), false, payload);
        t.end_s += kTurnaroundS + kAckBytes * kAirByteS;
        break;
      }
      ++counters_.lost_receptions;
      if (retries == options_.xbee.max_frame_retries) {
        status = 0x01;  // no ACK
        break;
      }
      ++retries;
      t = Transmit(t.end_s + kAckWaitS, air_s, options_.xbee, &channel_, &rng_);
      if (!t.sent) {
        ++counters_.csma_failures;
        status = 0x02;
        break;
      }
    }
  }
  if (frame_id != 0 && !modules_[from]->coordinator) {
    const uint64_t at = Cycles(t.end_s) + 1;
    if (options_.rx_frame_type == radio::kZigbeeRxFrameType) {
      WriteToModuleUart(
          from, at,
          {kZigbeeTxStatus, frame_id, 0xFF, 0xFE, static_cast<uint8_t>(retries), status, 0x00});
    } else {
      WriteToModuleUart(from, at, {kTxStatus802, frame_id, status});
    }
  }
}

void FirmwareWorld::Receive(size_t to, size_t from, uint64_t cycle, bool broadcast,
                            const std::vector<uint8_t>& payload) {
  std::uniform_real_distribution<double> rx(options_.xbee.rx_processing_min_s,
                                            options_.xbee.rx_processing_max_s);
  radio::ReceivePacket p;
  p.frame_type = options_.rx_frame_type;
  p.has_address64 = true;
  p.address64 = modules_[from]->address;
  if (p.frame_type == radio::kZigbeeRxFrameType) {
    p.has_address16 = true;
    p.address16 = 0xFFFE;
  } else {
    p.has_rssi = true;
    p.rssi_dbm = kRssiDbm;
  }
  p.options = broadcast ? 0x02 : 0x00;
  p.payload = payload;
  WriteToModuleUart(to, cycle + Cycles(rx(rng_)), radio::EncodeReceivePacket(p));
  if (modules_[to]->coordinator) {
    ++counters_.frames_to_coordinator;
    coordinator_frames_.push_back({cycle, p});
  }
}

void FirmwareWorld::WriteToModuleUart(size_t module, uint64_t cycle,
                                      const std::vector<uint8_t>& frame_data) {
  Module& m = *modules_[module];
  if (m.coordinator) {
    const std::vector<uint8_t> bytes =
        radio::EncodeFrame(frame_data.data(), frame_data.size(), options_.coordinator_api_mode);
    // 8N1: ten bits a byte at the coordinator's baud rate.
    const uint64_t byte_cycles = Cycles(10.0 / options_.coordinator_baud);
    uint64_t start = std::max(cycle, m.line_out_free);
    for (uint8_t b : bytes) {
      start += byte_cycles;
      At(start, [this, b] { coordinator_out_.push_back(b); });
    }
    m.line_out_free = start;
    return;
  }
  const std::vector<uint8_t> bytes =
      radio::EncodeFrame(frame_data.data(), frame_data.size(), options_.device_api_mode);
  const uint64_t byte_cycles = Cycles(10.0 / options_.device_baud);
  uint64_t start = std::max(cycle, m.line_out_free);
  AvrCore* core = devices_[module].core.get();
  for (uint8_t b : bytes) {
    // simavr makes a byte readable one of its byte times after it is
    // handed in: hand it in as its start bit goes out.
    core->SendUart(b, start);
    start += byte_cycles;
  }
  m.line_out_free = start;
}

void FirmwareWorld::TakeCoordinatorBytes(std::vector<uint8_t>* out) {
  out->insert(out->end(), coordinator_out_.begin(), coordinator_out_.end());
  coordinator_out_.clear();
}

void FirmwareWorld::OnBurstEdge(size_t index, uint64_t cycle) {
  const int64_t last = last_burst_edge_[index];
  last_burst_edge_[index] = static_cast<int64_t>(cycle);
  if (last >= 0 && cycle - static_cast<uint64_t>(last) < Cycles(kBurstQuietS)) return;
  Pulse(index, cycle);
}

std::array<double, 3> FirmwareWorld::BeaconPosition(const Device& d, uint64_t cycle) const {
  if (d.trajectory == nullptr) {
    return {site_.room.min_x_m + site_.room.size_x_m / 2,
            site_.room.min_y_m + site_.room.size_y_m / 2, d.height_m};
  }
  const GroundTruthPose p = d.trajectory->PoseAt(Seconds(cycle));
  return {p.x_m, p.y_m, d.height_m};
}

void FirmwareWorld::Pulse(size_t beacon, uint64_t fire_cycle) {
  ++counters_.pulses;
  const std::array<double, 3> b = BeaconPosition(devices_[beacon], fire_cycle);
  const double c = SpeedOfSound(site_.simulation.temperature_c);
  const std::array<double, 3> floor_middle = {site_.room.min_x_m + site_.room.size_x_m / 2,
                                              site_.room.min_y_m + site_.room.size_y_m / 2, 0.0};
  const double half_period_s = 0.5 / site_.acoustics.frequency_hz;
  for (size_t i = 0; i < devices_.size(); ++i) {
    const Device& r = devices_[i];
    if (r.role != Device::Role::kReceiver) continue;
    // The path heard: with obstacles the pulse may arrive round one
    // (AcousticScene), or not at all; without, the direct path with its
    // spreading and the air's absorption.
    AudiblePath heard;
    if (scene_) {
      heard = scene_->ShortestAudiblePath(Seconds(fire_cycle), b, r.position_m);
    } else {
      heard.kind = AudiblePath::Kind::kDirect;
      heard.direct_m = heard.length_m = Distance(b, r.position_m);
      heard.loss_db = 20.0 * std::log10(std::max(heard.length_m, 0.05)) +
                      decay_.air_absorption_db_per_m * heard.length_m;
    }
    // An echo arrives from its reflection point: the receiver's off-axis
    // loss is taken in that direction.
    const std::array<double, 3>& source =
        heard.kind == AudiblePath::Kind::kReflected ? heard.reflection_point_m : b;
    const double off_rad = OffAxisRad(r.position_m, source, floor_middle);
    PulseTruth truth;
    truth.beacon_id = devices_[beacon].id;
    truth.receiver_id = r.id;
    truth.fire_cycle = fire_cycle;
    truth.kind = heard.kind;
    truth.direct_m = heard.direct_m;
    truth.path_m = heard.kind == AudiblePath::Kind::kNone ? heard.direct_m : heard.length_m;
    truth.time_of_flight_s = truth.path_m / c;
    // Level over the threshold: the room's level at 1 m less the path's
    // loss and the receiver's off-axis loss (the beacon's emitter is
    // omnidirectional in azimuth, a cone over the transducer). Unheard: no
    // level at all.
    truth.level_db = heard.kind == AudiblePath::Kind::kNone
                         ? -std::numeric_limits<double>::infinity()
                         : decay_.level_at_1m_db - heard.loss_db -
                               options_.detector.off_axis_db_per_rad2 * off_rad * off_rad;
    if (truth.level_db > 0.0) {
      // Envelope 1 - exp(-t / tau) reaches the threshold 10^(-L/20) of its
      // amplitude; the comparator fires at the next carrier peak (the
      // rectified carrier peaks every half period, the first a quarter
      // period after the arrival).
      const double x = std::pow(10.0, -truth.level_db / 20.0);
      const double cross_s = options_.detector.rise_tau_s * std::log(1.0 / (1.0 - x));
      const double peaks = std::ceil(cross_s / half_period_s - 0.5);
      const double detect_s = truth.time_of_flight_s + (std::max(peaks, 0.0) + 0.5) * half_period_s;
      const uint64_t rise = fire_cycle + Cycles(detect_s);
      const uint64_t fall = fire_cycle + Cycles(truth.time_of_flight_s + decay_.decay_s);
      truth.detector_rise_cycle = static_cast<int64_t>(rise);
      DetectorHigh(i, options_.wiring.detector_pin, rise, std::max(fall, rise + 1));
      truth.strong = truth.level_db >= options_.detector.strong_margin_db;
      if (truth.strong) {
        const double xs = x * std::pow(10.0, options_.detector.strong_margin_db / 20.0);
        const double cross_strong = options_.detector.rise_tau_s * std::log(1.0 / (1.0 - xs));
        const double pk = std::ceil(cross_strong / half_period_s - 0.5);
        const uint64_t srise =
            fire_cycle + Cycles(truth.time_of_flight_s + (std::max(pk, 0.0) + 0.5) * half_period_s);
        DetectorHigh(i, options_.wiring.strong_echo_pin, srise, std::max(fall, srise + 1));
      }
    }
    pulses_.push_back(truth);
  }
}

void FirmwareWorld::DetectorHigh(size_t receiver, AvrPin pin, uint64_t rise, uint64_t fall) {
  const int k = pin == options_.wiring.detector_pin ? 0 : 1;
  uint64_t& until = high_until_[receiver][k];
  AvrCore* core = devices_[receiver].core.get();
  if (rise > until) core->DrivePin(pin, true, rise);
  if (fall <= until) return;
  until = fall;
  // Falls when no later pulse has extended the level meanwhile.
  At(fall, [this, receiver, k, pin, fall, core] {
    if (high_until_[receiver][k] == fall) core->DrivePin(pin, false, fall);
  });
}

}  // namespace roomfix::firmware
