#ifndef ROOMFIX_CORE_WORLD_SITE_LIMITS_H_
#define ROOMFIX_CORE_WORLD_SITE_LIMITS_H_

#include <cstddef>

namespace roomfix {

// The most of each list a site may hold. A site from the bus or a log is
// outside input, and every process and tool builds per-receiver,
// per-beacon, per-robot and per-camera structures from it (the survey's
// normal matrix grows with the square of the receivers: a log naming 10 000
// took 24 GB, issue #28), so ParseSite refuses a longer list with FILE:LINE
// before reading its entries, from a file and from a message alike. Each is
// well above a room's needs and tied to a limit elsewhere
// (docs/site_file.md, "Limits").

// A RANGES message carries at most 256 ranges (range_set_t.num_ranges).
inline constexpr size_t kMaxSiteReceivers = 256;
// trilat_proc keeps state for at most 256 beacons.
inline constexpr size_t kMaxSiteBeacons = 256;
// Robots (the site's, each camera's, the simulated ones).
inline constexpr size_t kMaxSiteRobots = 256;
// A site_t carries at most 16 calibration files, one per camera.
inline constexpr size_t kMaxSiteCameras = 16;
// Marker classes per camera (compared pairwise when parsed).
inline constexpr size_t kMaxCameraMarkerClasses = 64;
// Coordinators (radios), each on its own serial port.
inline constexpr size_t kMaxSiteRadios = 16;
// Points of a simulated waypoint trajectory.
inline constexpr size_t kMaxWaypoints = 10000;

}  // namespace roomfix

#endif  // ROOMFIX_CORE_WORLD_SITE_LIMITS_H_
