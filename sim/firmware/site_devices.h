#ifndef ROOMFIX_SIM_FIRMWARE_SITE_DEVICES_H_
#define ROOMFIX_SIM_FIRMWARE_SITE_DEVICES_H_

// The site's devices as the lab flashes them: the firmware images of
// firmware/ (build/firmware/beacon.elf and receiver.elf) and each device's
// EEPROM configuration as `roomfix devices` writes it (core/radio/
// device_config.h), so the simulation runs what the lab would.
#include <string>

#include "core/radio/device_config.h"
#include "core/world/site.h"
#include "sim/firmware/firmware_world.h"

namespace roomfix::firmware {

// Fills the ELF paths (firmware_dir/beacon.elf, receiver.elf), the EEPROM
// images of every device (radio::DeviceConfigsForSite with `config`), the
// devices' UART rate and the XBee model's mean processing times from
// config.radio, and the coordinator's address. False with *error when an
// ELF is missing or the site cannot be configured.
bool ConfigureFirmwareForSite(const Site& site, const radio::DeviceConfigOptions& config,
                              const std::string& firmware_dir, FirmwareWorldOptions* options,
                              std::string* error);

// build/firmware of the build tree this program was built in, or "" (a
// program installed from the package looks there first, then here).
std::string DefaultFirmwareDir();

}  // namespace roomfix::firmware

#endif  // ROOMFIX_SIM_FIRMWARE_SITE_DEVICES_H_
