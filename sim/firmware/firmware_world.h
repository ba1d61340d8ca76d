#ifndef ROOMFIX_SIM_FIRMWARE_FIRMWARE_WORLD_H_
#define ROOMFIX_SIM_FIRMWARE_FIRMWARE_WORLD_H_

// The beacons and wall receivers of a site as firmware: one simulated
// ATmega328P per device (AvrCore), each with an XBee module, in one room's
// air, advanced in lockstep; the coordinator's serial bytes come out for a
// pseudo-terminal (zigbee_bridge reads them) and its input goes back in.
//
// Lockstep. Every core's clock is the world's: cycle k of every core is
// k x 62.5 ns after the simulation's t = 0. The world advances in quanta of
// `quantum_cycles` (default 1600 = 100 us): it first delivers its events
// that fall in the quantum (a byte for a device's UART, a level on a
// detector pin) to the cores as cycle timers at their exact cycles, then
// runs each core to the quantum's end. What a core does in the quantum (a
// byte written to UDR0, an edge on the burst pin) reaches another core no
// sooner than the shortest cross-device delay: a radio frame needs at
// least a UART byte, the module's processing and the air (over 1 ms), a
// pulse at least the sound's flight from the beacon to the nearest
// receiver (1.4 ms at 0.5 m). As long as the quantum is shorter than that
// lookahead, every delivery lands in a later quantum and is exact to the
// cycle (a 62.5 ns tick is one cycle); the cores' `late_events` count the
// deliveries that were not, and the tests require none. A quantum is a
// trade of bookkeeping against how stale the coordinator's bytes may be in
// real time, not of accuracy.
//
// Acoustics. The pulse leaves the beacon at the cycle its firmware starts
// the burst on its burst pin (the first edge after a quiet millisecond). It
// reaches receiver i after |p_beacon - p_i| / c(T) (core/world's
// SpeedOfSound at the site's simulation temperature). The echo's level over
// the detector's threshold is the room's level at 1 m (ComputeRoomDecay)
// less spreading 20 log10(r), the air's absorption alpha r and the
// transducers' off-axis loss; below 0 dB nothing is heard. A resonant
// transducer's envelope rises as 1 - exp(-t / tau), so the threshold is
// crossed tau ln(1 / (1 - 10^(-L/20))) after the arrival, and the comparator
// fires on the first carrier half-cycle peak after that: a weak (far,
// off-axis) echo is timed later. The detector pin stays high while the
// pulse and its tail hold the receiver above threshold (RoomDecay::decay_s);
// a second comparator (the strong-echo pin) rises only for echoes at least
// `strong_margin_db` over the threshold, so the firmware can flag weak ones.
//
// Faults: radio losses per reception, a module that buffers (holds its
// frames and releases them in a burst), a device that reboots (its core is
// reset at a given time).

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <queue>
#include <random>
#include <string>
#include <vector>

#include "core/radio/xbee_frame.h"
#include "core/world/acoustic_paths.h"
#include "core/world/air_model.h"
#include "core/world/site.h"
#include "sim/firmware/avr_core.h"
#include "sim/firmware/xbee_timing.h"

namespace roomfix::firmware {

// Where the firmware's hardware is wired (the firmware's INTERFACE.md).
struct DeviceWiring {
  // The beacon's transducer driver: Timer1's OC1A.
  AvrPin burst_pin{'B', 1};
  // The receiver's echo detector (ICP1, rising edge) and its second,
  // higher-threshold comparator.
  AvrPin detector_pin{'B', 0};
  AvrPin strong_echo_pin{'D', 2};
};

// The detector's physics.
struct DetectorModel {
  // Envelope rise time constant of the transmitter-receiver transducer pair
  // (a 40 kHz ceramic pair of Q about 20: tau = Q / (pi f) = 160 us).
  double rise_tau_s = 160e-6;
  // Off-axis loss of each transducer at angle theta from its axis:
  // off_axis_db_per_rad2 x theta^2 (a piston of ka about 4 loses 6 dB at
  // 30 degrees: 6 / 0.274 = 22 dB/rad^2). Beacons point up, receivers at
  // the floor's middle.
  double off_axis_db_per_rad2 = 22.0;
  // The strong-echo comparator's threshold over the detector's.
  double strong_margin_db = 6.0;

  bool IsValid(std::string* error) const;
};

struct RadioFaultOptions {
  // Each module misses a frame on the air with this probability (a unicast
  // is retried by the MAC; a broadcast is not).
  double loss_probability = 0.0;
  // Per frame: the sending module starts holding its frames for up to
  // buffer_hold_max_s, then sends them back to back.
  double buffer_probability = 0.0;
  double buffer_hold_max_s = 0.15;

  bool IsValid(std::string* error) const;
};

// A device reset at a time: device index (FirmwareWorld::devices order), s.
struct Reboot {
  size_t device = 0;
  double at_s = 0.0;
};

struct FirmwareWorldOptions {
  std::string beacon_elf;
  std::string receiver_elf;
  // The EEPROM image of each device (its configuration from the site); an
  // empty image leaves the EEPROM erased.
  std::function<std::vector<uint8_t>(const Beacon&)> beacon_eeprom;
  std::function<std::vector<uint8_t>(const Receiver&)> receiver_eeprom;
  DeviceWiring wiring;
  DetectorModel detector;
  XbeeTimingOptions xbee;
  RadioFaultOptions faults;
  std::vector<Reboot> reboots;
  // The coordinator's serial line (zigbee_bridge --baud, --api-mode) and
  // the frame its module writes for each received packet (0x90 ZigBee,
  // 0x80 802.15.4 with a 64-bit source).
  double coordinator_baud = 115200.0;
  radio::ApiMode coordinator_api_mode = radio::ApiMode::kEscaped;
  uint8_t rx_frame_type = radio::kRx64FrameType;
  // The devices' modules' serial lines (their BD) and API mode (AP).
  double device_baud = 250000.0;
  radio::ApiMode device_api_mode = radio::ApiMode::kEscaped;
  // The coordinator module's 64-bit address (the receivers' reports are
  // sent there, unless they broadcast).
  uint64_t coordinator_address = 0;
  // Lockstep quantum, cycles (see above).
  uint64_t quantum_cycles = 1600;
  uint32_t frequency_hz = 16000000;
  // Host time of t = 0 of the trajectories; the coordinator's bytes carry it.
  int64_t start_utime = 0;
  uint64_t seed = 1;
  // Only receivers of this radio (site radios[].id) are simulated; 0: all.
  int radio_id = 0;

  bool IsValid(std::string* error) const;
};

// The truth about one pulse at one receiver, for tests.
struct PulseTruth {
  int beacon_id = 0;
  int receiver_id = 0;
  // Cycle the burst started, path length and its time of flight, and the
  // detector's rise (arrival + threshold crossing) or -1 when unheard.
  uint64_t fire_cycle = 0;
  double path_m = 0.0;
  double time_of_flight_s = 0.0;
  double level_db = 0.0;
  int64_t detector_rise_cycle = -1;
  bool strong = false;
  // The path heard (core/world/acoustic_paths.h): direct, a first-order
  // echo round an obstacle (path_m is then the echo's, longer than
  // direct_m), or none (blocked with no echo above threshold: unheard).
  AudiblePath::Kind kind = AudiblePath::Kind::kDirect;
  double direct_m = 0.0;
};

struct WorldCounters {
  int64_t pulses = 0;
  int64_t frames_from_devices = 0;
  int64_t frames_to_coordinator = 0;
  int64_t frames_from_coordinator = 0;
  int64_t broadcasts = 0;
  int64_t unicasts = 0;
  int64_t lost_receptions = 0;
  int64_t csma_failures = 0;
  int64_t buffered_frames = 0;
  int64_t device_frame_errors = 0;
  int64_t unknown_frame_types = 0;
  int64_t reboots = 0;
  int64_t baud_mismatches = 0;
  int64_t late_events = 0;
};

class FirmwareWorld {
 public:
  struct Device {
    enum class Role { kBeacon, kReceiver } role = Role::kReceiver;
    int id = 0;
    uint64_t address = 0;
    std::unique_ptr<AvrCore> core;
    // Beacons: the trajectory that carries it (nullptr: a fixed position at
    // the floor's middle) and its height.
    const Trajectory* trajectory = nullptr;
    double height_m = 0.0;
    std::array<double, 3> position_m{};
  };

  // nullptr with a one-line reason when an option is invalid or an ELF
  // does not load.
  static std::unique_ptr<FirmwareWorld> Create(const Site& site,
                                               const FirmwareWorldOptions& options,
                                               std::string* error);
  ~FirmwareWorld();

  // Runs every device to simulated time t_s (from t = 0).
  void AdvanceTo(double t_s);
  double now_s() const;
  uint64_t now_cycle() const { return now_cycle_; }

  // The coordinator's UART output due by now (in order), and bytes the PC
  // wrote to it (API frames for the coordinator's module to send).
  void TakeCoordinatorBytes(std::vector<uint8_t>* out);
  void FromCoordinator(const uint8_t* data, size_t size);

  // Resets device `index` now (a power cycle).
  void RebootDevice(size_t index);

  const std::vector<Device>& devices() const { return devices_; }
  const std::vector<PulseTruth>& pulses() const { return pulses_; }
  // Every receive frame the coordinator's module wrote, with the cycle its
  // last byte went out (tests check the firmware's payloads in them).
  struct CoordinatorFrame {
    uint64_t cycle = 0;
    radio::ReceivePacket packet;
  };
  const std::vector<CoordinatorFrame>& coordinator_frames() const { return coordinator_frames_; }
  const WorldCounters& counters() const { return counters_; }
  // Instructions all cores ran, for the benchmark.
  int64_t instructions() const;

 private:
  struct Module;
  struct Event {
    uint64_t cycle;
    uint64_t order;
    std::function<void()> run;
    bool operator>(const Event& o) const {
      return cycle != o.cycle ? cycle > o.cycle : order > o.order;
    }
  };

  FirmwareWorld(const Site& site, const FirmwareWorldOptions& options);
  bool AddDevices(std::string* error);
  void At(uint64_t cycle, std::function<void()> run);
  uint64_t Cycles(double s) const;
  double Seconds(uint64_t cycle) const;
  void OnDeviceUart(size_t index, uint64_t cycle, uint8_t byte);
  void OnModuleFrame(size_t module, uint64_t cycle, const uint8_t* data, size_t size);
  void SendOverAir(size_t from, uint64_t ready_cycle, uint64_t dest64, uint8_t frame_id,
                   std::vector<uint8_t> payload);
  void Receive(size_t to, size_t from, uint64_t cycle, bool broadcast,
               const std::vector<uint8_t>& payload);
  void WriteToModuleUart(size_t module, uint64_t cycle, const std::vector<uint8_t>& frame_data);
  void OnBurstEdge(size_t index, uint64_t cycle);
  void Pulse(size_t beacon, uint64_t fire_cycle);
  void DetectorHigh(size_t receiver, AvrPin pin, uint64_t rise, uint64_t fall);
  std::array<double, 3> BeaconPosition(const Device& d, uint64_t cycle) const;

  const Site& site_;
  FirmwareWorldOptions options_;
  RoomDecay decay_;
  // The site's obstacles, for non-line-of-sight from geometry; absent when
  // the site has none (the direct path is then all there is).
  std::optional<AcousticScene> scene_;
  std::mt19937_64 rng_;
  std::vector<Device> devices_;
  // One module per device, then the coordinator's (the last).
  std::vector<std::unique_ptr<Module>> modules_;
  AirChannelTimes channel_;
  std::priority_queue<Event, std::vector<Event>, std::greater<Event>> events_;
  uint64_t order_ = 0;
  uint64_t now_cycle_ = 0;
  // Per device: the last burst-pin edge (a new pulse after a quiet ms).
  std::vector<int64_t> last_burst_edge_;
  // Per device and detector pin: until when it is held high.
  std::vector<std::array<uint64_t, 2>> high_until_;
  std::vector<uint8_t> coordinator_out_;
  std::vector<PulseTruth> pulses_;
  std::vector<CoordinatorFrame> coordinator_frames_;
  WorldCounters counters_;
};

// The site's devices as FirmwareWorld simulates them: every receiver (of
// radio_id, or all) and every beacon a simulated robot carries.
size_t CountFirmwareDevices(const Site& site, int radio_id);

}  // namespace roomfix::firmware

#endif  // ROOMFIX_SIM_FIRMWARE_FIRMWARE_WORLD_H_
