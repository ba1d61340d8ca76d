#ifndef ROOMFIX_VIEWER_FOOTPRINT_H_
#define ROOMFIX_VIEWER_FOOTPRINT_H_

#include <map>
#include <string>
#include <vector>

#include "core/world/site.h"
#include "viewer/view_state.h"

namespace roomfix::viewer {

// Each camera's footprint: the floor polygon its image covers at
// `height_m` (the markers' plane, so a robot inside it is seen), from the
// camera's calibration text in `calibration_texts` (by camera id: the texts
// the site carries, SiteCalibrationText's) when it parses as a full model (a
// 9-region table is valid at its own height only and cannot say), else from
// the nominal model (straight down from mount_position_m, field_of_view_deg
// across the width: what a camera not yet calibrated should roughly see).
// The image border is walked (kFootprintSamplesPerSide pixels per side) and
// each pixel mapped to the plane; pixels whose ray misses it (beyond the
// horizon of a wide lens) are left out, so the polygon is the part of the
// border that does reach the floor.
//
// No file is opened: a site from the bus or a log names its calibrations
// by the path they had at the publisher, which on this host may be another
// file, a file outside the project (`/etc/passwd`, `../..`), or nothing; it
// refers only to the texts it carries (docs/messages.md, issue #28).
inline constexpr int kFootprintSamplesPerSide = 32;
std::vector<CameraFootprint> CameraFootprints(const Site& site,
                                              const std::map<int, std::string>& calibration_texts,
                                              double height_m);

// The marker height of the site's cameras' robots (the first listed), else
// 0: the plane the viewer draws footprints in.
double FootprintHeight(const Site& site);

}  // namespace roomfix::viewer

#endif  // ROOMFIX_VIEWER_FOOTPRINT_H_
