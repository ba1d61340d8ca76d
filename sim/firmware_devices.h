#ifndef ROOMFIX_SIM_FIRMWARE_DEVICES_H_
#define ROOMFIX_SIM_FIRMWARE_DEVICES_H_

// roomfix_sim --devices firmware: the site's beacons and receivers as their
// firmware in simavr (sim/firmware/firmware_world.h), paced by the wall
// clock, their coordinator's bytes on the pseudo-terminals zigbee_bridge
// reads. Built when simavr is installed; otherwise Create says so.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/world/site.h"
#include "sim/wall_devices.h"

namespace roomfix {

struct FirmwareDevicesOptions {
  // Folder of beacon.elf and receiver.elf ("" : the build tree's firmware/).
  std::string firmware_dir;
  // The faults that have a place in the firmware model: radio losses (the
  // larger of the lost-report and lost-announcement probabilities, per
  // module and frame), a buffering module, and the beacon's restarts (a
  // reset of its core every restart_every_s).
  RadioFaults faults;
  uint64_t seed = 1;
  // Host time of t = 0 (the ground truth's).
  int64_t start_utime = 0;
};

class FirmwareDevices {
 public:
  // nullptr with a one-line reason when simavr is not built in, the
  // firmware images are missing or the site cannot be configured.
  static std::unique_ptr<FirmwareDevices> Create(const Site& site,
                                                 const FirmwareDevicesOptions& options,
                                                 std::string* error);
  virtual ~FirmwareDevices() = default;
  // Runs the devices to now_utime (at most max_step_s of simulated time a
  // call, so a slow machine still serves its bus) and appends the
  // coordinator's bytes due by then.
  virtual void Advance(int64_t now_utime, double max_step_s, std::vector<uint8_t>* bytes) = 0;
  // Bytes the PC wrote to the coordinator.
  virtual void FromCoordinator(const uint8_t* data, size_t size) = 0;
  // Simulated seconds so far, and a one-line summary for the log.
  virtual double simulated_s() const = 0;
  virtual std::string Summary() const = 0;
};

}  // namespace roomfix

#endif  // ROOMFIX_SIM_FIRMWARE_DEVICES_H_
