#include "sim/firmware_devices.h"

#include <algorithm>

#ifdef ROOMFIX_HAVE_SIMAVR
#include "core/radio/device_config.h"
#include "sim/firmware/firmware_world.h"
#include "sim/firmware/site_devices.h"
#endif

namespace roomfix {

#ifdef ROOMFIX_HAVE_SIMAVR
namespace {

class SimavrDevices : public FirmwareDevices {
 public:
  explicit SimavrDevices(int64_t start_utime) : start_utime_(start_utime) {}
  bool Init(const Site& site, const FirmwareDevicesOptions& options, std::string* error) {
    firmware::FirmwareWorldOptions w;
    const std::string dir =
        options.firmware_dir.empty() ? firmware::DefaultFirmwareDir() : options.firmware_dir;
    if (!firmware::ConfigureFirmwareForSite(site, radio::DeviceConfigOptions{}, dir, &w, error)) {
      return false;
    }
    w.seed = options.seed;
    w.start_utime = options.start_utime;
    w.faults.loss_probability = std::max(options.faults.lost_report_probability,
                                         options.faults.lost_announcement_probability);
    w.faults.buffer_probability = options.faults.buffer_probability;
    w.faults.buffer_hold_max_s = options.faults.buffer_hold_max_s;
    // Devices are numbered receivers first, then beacons (FirmwareWorld).
    if (options.faults.restart_every_s > 0) {
      const size_t receivers = site.receivers.size();
      const size_t n = firmware::CountFirmwareDevices(site, 0);
      constexpr double kHorizonS = 24 * 3600.0;
      for (size_t d = receivers; d < n; ++d) {
        for (double t = options.faults.restart_every_s; t < kHorizonS;
             t += options.faults.restart_every_s) {
          w.reboots.push_back({d, t});
        }
      }
    }
    world_ = firmware::FirmwareWorld::Create(site, w, error);
    return world_ != nullptr;
  }
  void Advance(int64_t now_utime, double max_step_s, std::vector<uint8_t>* bytes) override {
    const double target = std::max(0.0, (now_utime - start_utime_) * 1e-6);
    world_->AdvanceTo(std::min(target, world_->now_s() + max_step_s));
    world_->TakeCoordinatorBytes(bytes);
  }
  void FromCoordinator(const uint8_t* data, size_t size) override {
    world_->FromCoordinator(data, size);
  }
  double simulated_s() const override { return world_->now_s(); }
  std::string Summary() const override {
    const firmware::WorldCounters& c = world_->counters();
    return std::to_string(world_->devices().size()) + " devices, " + std::to_string(c.pulses) +
           " pulses, " + std::to_string(c.frames_from_devices) + " frames from devices, " +
           std::to_string(c.frames_to_coordinator) + " to the coordinator, " +
           std::to_string(c.lost_receptions) + " lost, " + std::to_string(c.buffered_frames) +
           " buffered, " + std::to_string(c.reboots) + " reboots, " +
           std::to_string(c.late_events) + " late events";
  }

 private:
  int64_t start_utime_;
  std::unique_ptr<firmware::FirmwareWorld> world_;
};

}  // namespace
#endif

std::unique_ptr<FirmwareDevices> FirmwareDevices::Create(const Site& site,
                                                         const FirmwareDevicesOptions& options,
                                                         std::string* error) {
#ifdef ROOMFIX_HAVE_SIMAVR
  auto devices = std::make_unique<SimavrDevices>(options.start_utime);
  if (!devices->Init(site, options, error)) return nullptr;
  return devices;
#else
  (void)site;
  (void)options;
  *error =
      "--devices firmware: this roomfix_sim was built without simavr (apt-get install "
      "libsimavr-dev simavr, then rebuild)";
  return nullptr;
#endif
}

}  // namespace roomfix
