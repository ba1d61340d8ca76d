#include "sim/firmware/site_devices.h"

#include <sys/stat.h>

#include <map>
#include <memory>

namespace roomfix::firmware {

namespace {

bool IsFile(const std::string& path) {
  struct stat st {};
  return stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

}  // namespace

std::string DefaultFirmwareDir() {
#ifdef ROOMFIX_FIRMWARE_BUILD_DIR
  return ROOMFIX_FIRMWARE_BUILD_DIR;
#else
  return "";
#endif
}

bool ConfigureFirmwareForSite(const Site& site, const radio::DeviceConfigOptions& config,
                              const std::string& firmware_dir, FirmwareWorldOptions* options,
                              std::string* error) {
  options->beacon_elf = firmware_dir + "/beacon.elf";
  options->receiver_elf = firmware_dir + "/receiver.elf";
  for (const std::string& elf : {options->beacon_elf, options->receiver_elf}) {
    if (!IsFile(elf)) {
      *error = elf + ": no such firmware image (build the `firmware` target: avr-gcc)";
      return false;
    }
  }
  std::vector<radio::DeviceImage> images;
  if (!radio::DeviceConfigsForSite(site, config, &images, error)) return false;
  auto beacons = std::make_shared<std::map<int, std::vector<uint8_t>>>();
  auto receivers = std::make_shared<std::map<int, std::vector<uint8_t>>>();
  for (const radio::DeviceImage& image : images) {
    auto& table = image.config.role == radio::DeviceRole::kBeacon ? *beacons : *receivers;
    table[image.config.id] = radio::EncodeDeviceConfig(image.config);
  }
  // A device the images do not name keeps an erased EEPROM: its firmware
  // then reports the missing configuration, as a real one would.
  options->beacon_eeprom = [beacons](const Beacon& b) {
    auto it = beacons->find(b.id);
    return it == beacons->end() ? std::vector<uint8_t>{} : it->second;
  };
  options->receiver_eeprom = [receivers](const Receiver& r) {
    auto it = receivers->find(r.id);
    return it == receivers->end() ? std::vector<uint8_t>{} : it->second;
  };
  options->device_baud = config.radio.uart_baud;
  // The model's processing times centred on the firmware's nominal ones,
  // their spreads kept.
  XbeeTimingOptions& x = options->xbee;
  const double tx_half = (x.tx_processing_max_s - x.tx_processing_min_s) / 2;
  const double rx_half = (x.rx_processing_max_s - x.rx_processing_min_s) / 2;
  x.tx_processing_min_s = config.radio.tx_processing_us * 1e-6 - tx_half;
  x.tx_processing_max_s = config.radio.tx_processing_us * 1e-6 + tx_half;
  x.rx_processing_min_s = config.radio.rx_processing_us * 1e-6 - rx_half;
  x.rx_processing_max_s = config.radio.rx_processing_us * 1e-6 + rx_half;
  if (config.coordinator_address != 0xFFFF)
    options->coordinator_address = config.coordinator_address;
  return true;
}

}  // namespace roomfix::firmware
